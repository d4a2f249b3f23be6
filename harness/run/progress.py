"""The run's progress bar: cases done, and the time left from the predicted CPU still
to run, not from the count of cases (the dearest lines run first, so the rate of
cases says nothing of what is left)."""

from __future__ import annotations

import sys
import time

#: seconds between two estimates of the time left (each sums every line's prediction)
EVERY_S = 2.0


def bar(total: int, initial: int, enabled: bool):
    """A tqdm bar of ``total`` cases on standard error, ``initial`` of them done;
    give it ``left`` (:func:`time_left`) once the schedule exists."""
    from tqdm import tqdm

    tqdm.monitor_interval = 0  # no monitor thread: workers are forked

    class Bar(tqdm):
        left = None      # () -> predicted seconds of wall time still to run, or None
        _shown = -EVERY_S

        def update(self, n=1):
            now = time.monotonic()
            if self.left is not None and now - self._shown >= EVERY_S:
                self._shown = now
                left = self.left()
                if left is not None:
                    self.set_postfix_str(f"≈{_duration(left)} left (predicted CPU)",
                                         refresh=False)
            return super().update(n)

    return Bar(total=total, initial=initial, disable=not enabled, file=sys.stderr,
               unit="case", dynamic_ncols=True)


def time_left(schedule, workers: int):
    """``() -> seconds``: the predicted CPU of ``schedule``'s cases not yet handed
    out (:meth:`~integrator_bench.harness.run.schedule.Schedule.predicted_left`)
    over ``workers``."""
    return lambda: schedule.predicted_left() / max(workers, 1)


def _duration(seconds: float) -> str:
    """``42 s``, ``12 min``, ``1.5 h``."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"
