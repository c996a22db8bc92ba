"""The joint loop as it runs, for autotune's design: :mod:`jointctl.metrics.step_loop` (it lives with the
metrics, below the scenario layer, because the step analysis predicts a run's figures with it too)."""

from jointctl.metrics.step_loop import (SATURATION_MARGIN, SETTLING_BAND, HoldingEffort, JointLoop, StepFigures,
                                        holding_effort, reference_step, step_figures)

__all__ = ["HoldingEffort", "JointLoop", "SATURATION_MARGIN", "SETTLING_BAND", "StepFigures", "holding_effort",
           "reference_step", "step_figures"]
