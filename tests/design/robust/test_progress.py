"""design's progress reports are the one common Progress type."""

from common.progress import Progress as BaseProgress
from design.robust.pipeline import Progress


def test_robust_progress_is_common_progress_and_aliases_agree():
    p = Progress("active learning", 60, 100, 0.91, None, "fit")
    assert isinstance(p, BaseProgress)
    assert (p.phase, p.simulations, p.budget) == (p.stage, p.done, p.total) == ("active learning", 60, 100)
    assert p.cv_accuracy == 0.91 and p.message == "fit" and p.unit == "simulations"
    assert p.fraction == 0.6
