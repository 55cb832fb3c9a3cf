"""Progress numbers that keep rising over a whole run.

A run is often several optimisations in turn — the filter error method's R cycles and
active sets, multiple shooting's defect-weight stages, MNR's second opinion after MNRES —
each with its own ``Objective``, whose passes and evaluations count from zero. The user's
progress callback ``progress(pass, evaluations, cost)`` must not see those restarts:
``RunProgress`` adds to each stage's numbers the passes already reported and the
evaluations already spent, so both only grow from the first call to the last.
"""

from __future__ import annotations

from collections.abc import Callable

__all__ = ["Progress", "RunProgress", "next_stage"]

Progress = Callable[[int, int, float], None]


class RunProgress:
    """``progress(pass, evaluations, cost)`` numbered over the whole run.

    Args:
        progress: the user's callback.

    Call ``next_stage(evaluations)`` before a new objective starts reporting: its pass 0
    is then reported as the pass after the last one reported, and its evaluations on top of
    ``evaluations`` (the run's total so far; never less than the last count reported).
    """

    def __init__(self, progress: Progress) -> None:
        self.progress = progress
        self.pass_offset = 0
        self.evaluation_offset = 0
        self.last_pass = -1  # the last pass number reported (−1: none yet)
        self.last_evaluations = 0

    @classmethod
    def wrap(cls, progress: Progress | None) -> RunProgress | None:
        """None for None, else a ``RunProgress`` around ``progress``."""
        return None if progress is None else cls(progress)

    def __call__(self, passes: int, evaluations: int, cost: float) -> None:
        # reported pass = the stage's pass + the passes of earlier stages
        self.last_pass = max(self.last_pass, self.pass_offset + int(passes))
        total = self.evaluation_offset + int(evaluations)
        self.last_evaluations = max(self.last_evaluations, total)
        self.progress(self.last_pass, self.last_evaluations, cost)

    def next_stage(self, evaluations: int = 0) -> None:
        """The next stage's numbers continue after this one's (class docstring)."""
        self.pass_offset = self.last_pass + 1
        self.evaluation_offset = max(int(evaluations), self.last_evaluations)


def next_stage(progress: object, evaluations: int = 0) -> None:
    """``progress.next_stage(evaluations)`` when ``progress`` is a ``RunProgress``."""
    if isinstance(progress, RunProgress):
        progress.next_stage(evaluations)
