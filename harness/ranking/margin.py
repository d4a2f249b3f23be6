"""How sure a ranking is: the margin of one line over another, with its interval.

One timed solve of a case moves by a median 8-16 % between identical runs, and
up to 2x, so a ranking read off single samples names whichever line was lucky.
The ranking here names a winner only when the noise cannot reverse it.

A line's CPU to reach a target is read off one or two of its records, the
points that bracket the crossing (:func:`~integrator_bench.harness.ranking.reach.reach_line`):
``cpu = cpu_j**(1 - w) * cpu_k**w``, the weight ``w`` fixed by the errors alone.
Each record keeps the CPU of every timed solve (``cpu_samples``); taken sample
by sample, they give the line's **samples of the CPU to reach the target**
(:func:`crossing_samples`). The contenders' rounds
(:mod:`integrator_bench.harness.contend`) time every bracketing record of the
lines in contention once per round, alternating between them in one process,
so the i-th last sample of one line and of another were taken side by side:
samples are paired from the end.

The **margin** of a line B over the cheapest line A is ``median(B) /
median(A)`` over their paired samples; its interval (:data:`LEVEL`, 95 %) is
the percentile bootstrap of that ratio, the pairs resampled together
(:func:`margin`; Efron and Tibshirani, *An Introduction to the Bootstrap*,
1993, ch. 13). The resampling is seeded, so one store gives one report. Fewer
than :data:`MIN_PAIRED` paired samples give no interval: the margin is
*unmeasured*.

A line whose CPU to reach the target is more than :data:`BAND` times the
cheapest's is out of contention: a 2x gap is beyond what the noise of single
samples reaches at its 90th percentile (1.4-1.7x, docs/timing.md), so its rank
holds without more samples. Of the lines within the band (the *contenders*),
:func:`verdict` says:

* ``winner``: every contender's margin interval lies above 1;
* ``tie``: some contender is not clearly slower: its interval reaches 1 (or
  lies below it: the cheaper by the samples is the other one), or it has none
  (fewer than :data:`MIN_PAIRED` paired samples: records of an older store, a
  contest the contenders' cap left out), since then the noise may reverse the
  ranking; those lines tie with the cheapest.

References: B. Efron and R. J. Tibshirani, *An Introduction to the Bootstrap*,
Chapman & Hall (1993), ch. 13 (percentile intervals); V. Stinner, pyperf
(several worker processes, warmups discarded); asv and BenchmarkTools.jl (a
change called only outside the noise).
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np

#: a line within this factor of the cheapest line's CPU to reach a target is a contender
BAND = 2.0
#: the confidence level of a margin's interval
LEVEL = 0.95
#: the fewest paired samples a margin's interval is given for
MIN_PAIRED = 5
#: bootstrap resamples of a margin's interval
RESAMPLES = 2000
#: a margin whose interval lies within [1 / EQUAL, EQUAL] is settled as a tie: more
#: samples would name no winner by a margin that matters
EQUAL = 1.05


def samples(value) -> np.ndarray | None:
    """A record's ``cpu_samples`` (JSON text or a sequence) as an array; None when
    the record has none (an older store, a record that was not timed)."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return None
    if isinstance(value, str):
        value = json.loads(value)
    out = np.asarray(value, float)
    return out if out.size and np.all(out > 0) else None


def crossing_samples(s_j, s_k, w: float) -> np.ndarray | None:
    """Samples of a line's CPU to reach a target between its points ``j`` and ``k``
    with weight ``w`` (``cpu_j**(1 - w) * cpu_k**w``), the two points' samples
    paired from the end; ``s_k`` alone when ``w`` is NaN (the target reached at a
    point, or an upper bound). None when a point has no samples."""
    if s_k is None:
        return None
    if w is None or math.isnan(w):
        return s_k
    if s_j is None:
        return None
    n = min(len(s_j), len(s_k))
    return np.exp((1 - w) * np.log(s_j[-n:]) + w * np.log(s_k[-n:]))


@dataclasses.dataclass(frozen=True)
class Margin:
    """A line's margin over the cheapest: ``ratio`` its CPU over the cheapest's
    (medians of their ``n`` paired samples), ``low``-``high`` its interval at
    :data:`LEVEL` (NaN when unmeasured: fewer than :data:`MIN_PAIRED` pairs)."""

    line: str
    ratio: float
    low: float = math.nan
    high: float = math.nan
    n: int = 0

    @property
    def measured(self) -> bool:
        return not math.isnan(self.low)

    @property
    def clear(self) -> bool:
        """The line is slower than the cheapest beyond the noise."""
        return self.measured and self.low > 1.0

    @property
    def settled(self) -> bool:
        """More samples would change nothing the ranking says: the line is clearly
        slower, or its interval lies within [1 / :data:`EQUAL`, :data:`EQUAL`]."""
        return self.clear or (self.measured and self.low >= 1 / EQUAL and self.high <= EQUAL)

    def text(self, over: bool = False) -> str:
        """``margin 1.04, 95 % 0.91-1.19`` (``margin 1.3, interval not measured``;
        ``margin 1.3, exact`` when every sample is the same, as counted work is);
        with ``over``, the line's name after the ratio (``margin 1.3 over B (ode),
        ...``)."""
        return f"margin {self.ratio:.3g}{f' over {self.line}' if over else ''}, {self.interval()}"

    def interval(self) -> str:
        """``95 % 0.91-1.19``, ``exact`` or ``interval not measured``."""
        if not self.measured:
            return "interval not measured"
        if self.low == self.high:
            return "exact"
        return f"{LEVEL * 100:.0f} % {self.low:.3g}-{self.high:.3g}"

    def short(self) -> str:
        """``1.3x (95 % 1.2-1.4)``: the answers' table's margin."""
        return f"{self.ratio:.2g}x ({self.interval()})"


def margin(line: str, best, other, ratio: float | None = None,
           level: float = LEVEL, resamples: int = RESAMPLES) -> Margin:
    """The margin of ``other`` over ``best``, two lines' samples of the CPU to reach
    a target (:func:`crossing_samples`), paired from the end.

    Parameters
    ----------
    line : str
        How the other line is named (``"label (formulation)"``).
    best, other : numpy.ndarray or None
        The samples; None when unknown.
    ratio : float, optional
        The ratio to give when there are too few pairs for an interval (the
        table's CPUs); default: the ratio of the samples' medians.
    level : float
        Confidence level of the interval.
    resamples : int
        Bootstrap resamples (seeded: the same samples give the same interval).
    """
    n = 0 if best is None or other is None else min(len(best), len(other))
    if n == 0:
        return Margin(line, math.nan if ratio is None else ratio)
    a, b = np.asarray(best[-n:], float), np.asarray(other[-n:], float)
    point = float(np.median(b) / np.median(a))
    if n < MIN_PAIRED:
        return Margin(line, point if ratio is None else ratio, n=n)
    rng = np.random.default_rng(n)
    idx = rng.integers(0, n, size=(resamples, n))
    boot = np.median(b[idx], axis=1) / np.median(a[idx], axis=1)
    tail = (1 - level) / 2 * 100
    low, high = np.percentile(boot, [tail, 100 - tail])
    return Margin(line, point, float(low), float(high), n)


def verdict(margins) -> str:
    """``winner`` or ``tie`` from the contenders' margins over the cheapest line
    (module docstring); ``winner`` when there are none."""
    return "winner" if all(m.clear for m in margins) else "tie"
