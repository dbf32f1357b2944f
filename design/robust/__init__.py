"""Robust layouts of chain-reaction contraptions (thesis 4.5-4.8).

Parametric success probability (PSP) learned from simulations by SVM active learning, factorized per event,
layout optimization under physical-validity constraints, robustness measures ρ_l / ρ_g and the baselines B1-B3.
Everything works in the normalized design space through the small :class:`~design.robust.problem.LayoutProblem`
protocol; :mod:`design.robust.contraption` adapts the contraption simulation core to it.
"""

from design.lazy import lazy_exports

# Names are imported on first use (PEP 562): ``design.robust.settings`` loads without scikit-learn, scipy and
# pybullet, so the CLI builds its parser (and answers --help) at once.
_SOURCES = {
    "baselines": ("BaselineResult", "baseline_b1", "baseline_b2", "baseline_b3"),
    "budget": ("Progress",),
    "executor": ("SimulationCache", "SimulationExecutor"),
    "optimize": ("optimize_layout", "smooth_minimum"),
    "pipeline": ("Comparison", "RobustLayout", "compare_methods", "optimize_robust_layout"),
    "problem": ("LayoutProblem", "RobustError", "SyntheticProblem", "synthetic_branching", "synthetic_chain"),
    "psp": ("CalibratedSVM", "FactorizedPSP", "explore"),
    "robustness": ("RobustnessCurve", "evaluation_layouts", "evaluation_set", "robustness_curve"),
    "settings": ("METHODS", "PSPSettings", "RobustnessSettings"),
}
__getattr__, __dir__, _MODULE_OF = lazy_exports(__name__, _SOURCES)

__all__ = [
    "METHODS", "BaselineResult", "CalibratedSVM", "Comparison", "FactorizedPSP", "LayoutProblem", "PSPSettings",
    "Progress", "RobustError", "RobustLayout", "RobustnessCurve", "RobustnessSettings", "SimulationCache",
    "SimulationExecutor", "SyntheticProblem", "baseline_b1", "baseline_b2", "baseline_b3", "compare_methods",
    "evaluation_layouts", "evaluation_set", "explore", "optimize_layout", "optimize_robust_layout", "robustness_curve",
    "smooth_minimum", "synthetic_branching", "synthetic_chain",
]
