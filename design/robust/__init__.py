"""Robust layouts of chain-reaction contraptions (thesis 4.5-4.8).

Parametric success probability (PSP) learned from simulations by SVM active learning, factorized per event,
layout optimization under physical-validity constraints, robustness measures ρ_l / ρ_g and the baselines B1-B3.
Everything works in the normalized design space through the small :class:`~design.robust.problem.LayoutProblem`
protocol; :mod:`design.robust.contraption` adapts the contraption simulation core to it.
"""

from design.robust.baselines import BaselineResult, baseline_b1, baseline_b2, baseline_b3
from design.robust.executor import SimulationCache, SimulationCancelled, SimulationExecutor
from design.robust.optimize import optimize_layout, smooth_minimum
from design.robust.pipeline import (
    METHODS,
    Comparison,
    Progress,
    RobustLayout,
    compare_methods,
    optimize_robust_layout,
)
from design.robust.problem import LayoutProblem, RobustError, SyntheticProblem, synthetic_branching, synthetic_chain
from design.robust.psp import CalibratedSVM, FactorizedPSP, explore
from design.robust.robustness import RobustnessCurve, evaluation_layouts, evaluation_set, robustness_curve
from design.robust.settings import PSPSettings, RobustnessSettings

__all__ = [
    "METHODS", "BaselineResult", "CalibratedSVM", "Comparison", "FactorizedPSP", "LayoutProblem", "PSPSettings",
    "Progress", "RobustError", "RobustLayout", "RobustnessCurve", "RobustnessSettings", "SimulationCache",
    "SimulationCancelled", "SimulationExecutor", "SyntheticProblem", "baseline_b1", "baseline_b2", "baseline_b3",
    "compare_methods", "evaluation_layouts", "evaluation_set", "explore", "optimize_layout", "optimize_robust_layout",
    "robustness_curve", "smooth_minimum", "synthetic_branching", "synthetic_chain",
]
