"""Integer-sequence optimisers of Paper A: MSMFO (Eq. 21–28) and the MFO/GA/PSO/SA baselines of its benchmark.

Public entry point::

    from controllers.mcf_dmpc.optim import minimize_sequence, OptimResult
    res = minimize_sequence(fitness, dim=60, n_values=3, method="msmfo", rng=np.random.default_rng(0))

``fitness`` maps a ``(m, D)`` array of zero-based indices to ``(m,)`` costs (vectorise the rollout over rows).
Modules: :mod:`.rounding` (Eq. 21, 22), :mod:`.evaluation` (counting/budget/result), :mod:`.mothflame` (MFO and
MSMFO, Eq. 23–28), :mod:`.baselines` (GA, PSO, SA), :mod:`.minimize` (the dispatcher).
"""

from .baselines import GaSettings, PsoSettings, SaSettings
from .evaluation import Evaluator, OptimResult
from .minimize import METHODS, method_settings, minimize_sequence
from .mothflame import (
    MFO_SETTINGS,
    MSMFO_SETTINGS,
    MothFlameSettings,
    chaotic_positions,
    flame_count,
    greedy_refine,
    mutation_probability,
)
from .rounding import clamp_round, cyclic_round, logistic_tent

__all__ = [
    "METHODS",
    "MFO_SETTINGS",
    "MSMFO_SETTINGS",
    "Evaluator",
    "GaSettings",
    "MothFlameSettings",
    "OptimResult",
    "PsoSettings",
    "SaSettings",
    "chaotic_positions",
    "clamp_round",
    "cyclic_round",
    "flame_count",
    "greedy_refine",
    "logistic_tent",
    "method_settings",
    "minimize_sequence",
    "mutation_probability",
]
