"""Plausibility of cutting-force coefficients: catch unit slips before a lobe diagram is computed.

Documented ranges for metals (specific cutting-force coefficients of the
linear/mechanistic model, Altintas, *Manufacturing Automation*, ch. 2 and
the coefficient tables of Kienzle-type data): the tangential coefficient K_t
lies between about 1e8 Pa (soft aluminium, 300-800 MPa typical) and 1e10 Pa
(hardened steels, nickel and titanium alloys up to a few GPa), and the radial
to tangential ratio K_r/K_t between about 0.05 and 2.  Values outside are
almost always a unit slip (MPa typed without ``e6``, N/mm^2 read as Pa, a
factor 1000) or swapped options.

:func:`check_cutting_coefficients` raises :class:`~bayes_rcsa.errors.SetupError`
with a one-line message naming the likely slip ("did you mean 790e6 Pa?"), or,
with ``allow_unusual=True``, returns that message as a warning.  Values
outside the physically meaningful range ``ABSURD_PA`` are refused even then.
"""

from __future__ import annotations

import math

from ..errors import SetupError

__all__ = ["KT_RANGE_PA", "RATIO_RANGE", "ABSURD_PA", "check_cutting_coefficients"]

KT_RANGE_PA = (1e8, 1e10)
RATIO_RANGE = (0.05, 2.0)
ABSURD_PA = (1e5, 1e13)
_SCALES = ((1e6, "e6", "MPa or N/mm^2 typed without e6"), (1e9, "e9", "GPa typed without e9"),
           (1e-3, "e-3", "1000 times too large"), (1e-6, "e-6", "Pa given as micro-units"), (1e3, "e3", "kPa"))


def _fmt(v: float) -> str:
    """Engineering notation as typed on a command line: 790e6, 2.3e9, 0.5."""
    if v == 0 or not math.isfinite(v) or 1e-3 <= abs(v) < 1e3:
        return f"{v:.4g}"
    e = int(math.floor(math.log10(abs(v)) / 3) * 3)
    return f"{v / 10**e:.4g}e{e}"


def _suggest(value: float, ok) -> str:
    for factor, _, why in _SCALES:
        if ok(value * factor):
            return f"; did you mean {_fmt(value * factor)} Pa ({why})?"
    return ""


def _in(v, lo, hi):
    return lo <= v <= hi


def check_cutting_coefficients(kt: float, kr: float, allow_unusual: bool = False) -> list[str]:
    """Check K_t and K_r (Pa) against the ranges for metals.

    Parameters
    ----------
    kt, kr : float, Pa
    allow_unusual : bool
        Return the messages as warnings instead of raising (values outside
        ``ABSURD_PA`` or negative values are refused regardless).

    Returns
    -------
    list of str, warnings (empty when the values are plausible)

    Raises
    ------
    SetupError
        Negative or non-finite values, values outside ``ABSURD_PA``, and, unless
        ``allow_unusual``, anything outside ``KT_RANGE_PA`` / ``RATIO_RANGE``.
    """
    for name, v in (("--kt", kt), ("--kr", kr)):
        if not math.isfinite(v):
            raise SetupError(f"{name} {v!r}: expected a finite coefficient in Pa")
        if v < 0 or (name == "--kt" and v == 0):
            raise SetupError(f"{name} {_fmt(v)}: cutting-force coefficients are magnitudes in Pa and must be "
                             f"{'> 0' if name == '--kt' else '>= 0'} (the force direction is in the cutting model)")
    messages = []
    lo, hi = KT_RANGE_PA
    if not _in(kt, lo, hi):
        messages.append(f"--kt {_fmt(kt)} Pa is outside {lo:.0e}-{hi:.0e} Pa, the range for metals"
                        + _suggest(kt, lambda v: _in(v, lo, hi)))
    else:
        r_lo, r_hi = RATIO_RANGE
        ratio = kr / kt
        if not _in(ratio, r_lo, r_hi):
            hint = _suggest(kr, lambda v: _in(v / kt, r_lo, r_hi))
            if not hint and kr > 0 and _in(kr, lo, hi) and _in(kt / kr, r_lo, r_hi):
                hint = "; were --kt and --kr swapped?"
            messages.append(f"--kr {_fmt(kr)} Pa gives Kr/Kt = {ratio:.3g}, outside {r_lo:g}-{r_hi:g} for metals"
                            + hint)
    for name, v in (("--kt", kt), ("--kr", kr)):
        if v > 0 and not _in(v, *ABSURD_PA):
            raise SetupError(f"{name} {_fmt(v)} Pa is outside {ABSURD_PA[0]:.0e}-{ABSURD_PA[1]:.0e} Pa, where no "
                             f"cutting model applies{_suggest(v, lambda u: _in(u, lo, hi))}")
    if messages and not allow_unusual:
        raise SetupError(messages[0] + " (use --allow-unusual to proceed anyway)")
    return messages
