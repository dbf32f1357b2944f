"""Placement jigs: laser-cut stands and templates that set a contraption's heights, tilts and tight positions by
touch (:mod:`design.jigs.plan`), their engraved tags (:mod:`design.jigs.engrave`) and pictures
(:mod:`design.jigs.render`)."""

from design.jigs.plan import ByHand, Jig, JigPlan, JigSettings, PartInput, Piece, plan_jigs

__all__ = ["ByHand", "Jig", "JigPlan", "JigSettings", "PartInput", "Piece", "plan_jigs"]
