"""Integrator settings: the controls a user of a code turns, declared and checked.

An integrator declares its settings as a tuple of :class:`Setting` in its
class attribute ``settings`` (numerics only: what a control means and which
values it takes). An instance carries the values it runs with
(:func:`resolve`: the defaults filled in, every value checked), as its
attribute ``setting_values`` and as an instance attribute of each setting's
name; the wrappers read them from there.

Where a setting is one of the controls a user of ADAMS/Solver tunes, ``control``
names it (the ADAMS seminar's list of integrator controls: ERROR, HINIT, HMAX,
HMIN, KMAX, MAXIT, PATTERN), so the seed's advice ("KMAX ... useful for models
with contact and/or very stiff elements. Recommended then to reduce to 2")
reads directly as ``max_order=2``.

References: MSC Software, ADAMS/Solver seminar, integrator controls
(INTEGRATOR statement); Rackauckas et al., SciMLBenchmarks "setups" (an
algorithm with its options).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


class SettingError(ValueError):
    """A setting name or value an integrator does not take (one line, naming the
    valid settings and their ranges)."""


@dataclass(frozen=True)
class Setting:
    """One control of an integrator.

    Attributes
    ----------
    name : str
        lower_snake name, as given on the command line (``max_order``).
    type : type
        ``int``, ``float`` or ``str``.
    default : object
        The value when the setting is not given; None means the code's own
        choice (no bound, its own first step), which the user cannot name.
    meaning : str
        One line: what it does.
    low, high : float or None
        Closed valid range of a number (None: unbounded on that side).
    choices : tuple or None
        The valid values of a ``str`` setting.
    control : str or None
        The ADAMS/Solver control it corresponds to (KMAX, HMAX, ...), if any.
    positive : bool
        A number that must be strictly greater than ``low`` (step sizes).
    """

    name: str
    type: type
    default: object
    meaning: str
    low: float | None = None
    high: float | None = None
    choices: tuple | None = None
    control: str | None = None
    positive: bool = False

    def valid(self) -> str:
        """The valid values in words: ``int in [1, 5]``, ``one of dense, sparse``."""
        if self.choices is not None:
            return "one of " + "|".join(map(str, self.choices))
        lo = "-inf" if self.low is None else f"{self.low:g}"
        hi = "inf" if self.high is None else f"{self.high:g}"
        left = "(" if self.positive or self.low is None else "["
        return f"{self.type.__name__} in {left}{lo}, {hi}{']' if self.high is not None else ')'}"

    def describe(self) -> str:
        """``max_order=int in [1, 5] (default 5, KMAX)``."""
        default = "the code's own" if self.default is None else f"{self.default:g}" \
            if isinstance(self.default, float) else str(self.default)
        control = f", {self.control}" if self.control else ""
        return f"{self.name}={self.valid()} (default {default}{control})"

    def check(self, value):
        """``value`` (a string from the command line, or a number) as this
        setting's type; :class:`SettingError`, naming the value as given, when
        it is not valid."""
        given = value
        try:
            if self.type is int and isinstance(value, str):
                number = float(value)
                if not number.is_integer():
                    raise ValueError
                value = int(number)
            else:
                value = self.type(value)
        except (TypeError, ValueError):
            raise SettingError(f"{self.name}={given} is not {self.valid()}") from None
        if self.choices is not None:
            if value not in self.choices:
                raise SettingError(f"{self.name}={given} is not {self.valid()}")
            return value
        if isinstance(value, float) and not math.isfinite(value):
            raise SettingError(f"{self.name}={given} is not {self.valid()}")
        below = self.low is not None and (value <= self.low if self.positive else value < self.low)
        if below or (self.high is not None and value > self.high):
            raise SettingError(f"{self.name}={given} is not {self.valid()}")
        return value

    def as_dict(self) -> dict:
        """For ``ibench list integrators --json``."""
        return {"name": self.name, "type": self.type.__name__, "default": self.default,
                "valid": self.valid(), "meaning": self.meaning, "control": self.control}


def resolve(owner: str, settings: tuple, given: dict) -> dict:
    """Every setting's value: ``given`` checked (strings converted), the defaults
    filled in.

    Raises
    ------
    SettingError
        One line naming ``owner`` (the integrator), the bad name or value and
        every valid setting with its range.
    """
    declared = {s.name: s for s in settings}
    valid = "; ".join(s.describe() for s in settings) or "none"
    values = {s.name: s.default for s in settings}
    for name, value in given.items():
        if name not in declared:
            raise SettingError(f"{owner} has no setting {name!r}; valid settings: {valid}")
        try:
            values[name] = declared[name].check(value)
        except SettingError as exc:
            raise SettingError(f"{owner}: {exc}; valid settings: {valid}") from None
    return values


def changed(settings: tuple, values: dict) -> dict:
    """The values of ``values`` that differ from their setting's default."""
    return {s.name: values[s.name] for s in settings
            if s.name in values and values[s.name] != s.default}


def label(values: dict) -> str:
    """``max_order=2, max_step=0.0001`` (sorted; ``""`` for none)."""
    return ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}"
                     for k, v in sorted(values.items()))


def variant_name(integrator: str, values: dict) -> str:
    """``cvode-bdf`` at the defaults, ``cvode-bdf (max_order=2)`` with settings."""
    return f"{integrator} ({label(values)})" if values else integrator


# Settings shared by several integrators: one declaration each.
MAX_STEP = Setting("max_step", float, None, "largest step size the code may take", low=0.0,
                   positive=True, control="HMAX")
FIRST_STEP = Setting("first_step", float, None, "size of the first step", low=0.0,
                     positive=True, control="HINIT")
MIN_STEP = Setting("min_step", float, None, "smallest step size before the code gives up",
                   low=0.0, positive=True, control="HMIN")
NEWTON_MAXIT = Setting("max_newton", int, 4, "Newton iterations per step before the step "
                       "counts as a convergence failure", low=1, high=100, control="MAXIT")
JACOBIAN_EVERY = Setting("jacobian_every", int, 0, "a new Jacobian every k Newton iterations "
                         "(1: full Newton); 0: only after a convergence failure", low=0,
                         high=1000, control="PATTERN")
MAX_STEPS = Setting("max_steps", int, None, "most steps the code may take", low=1)


def max_order(highest: int) -> Setting:
    """The maximum order of a variable-order multistep code whose highest (and
    default) order is ``highest``."""
    return Setting("max_order", int, highest, "highest order of the multistep method",
                   low=1, high=highest, control="KMAX")
