"""The unit policy of every human output: how a number reads on stderr, in Markdown and in HTML.

Machine outputs (JSON, netCDF, CSV) keep SI units and unit-suffixed keys; everything a person reads goes
through the functions here, so that one number reads the same on the terminal, in ``summary.md`` and in the
HTML reports (docs/data-formats.md, "Numbers for people"):

* lengths and depths in mm (:func:`mm`): three decimals from 0.01 mm up (``0.164 mm``), two significant digits
  below (``0.00039 mm``), never metres and never an exponent;
* clamping lengths in mm as given (:func:`length_mm`, ``25 mm``);
* spindle speeds in whole rpm (:func:`rpm`, ``13647 rpm``);
* frequencies in Hz with the digits their interval justifies, its width to about two significant digits
  (:func:`hz`, ``859.89 Hz (859.85–859.94)``);
* stiffness, damping, cutting coefficients: three significant digits in engineering form, the exponent a
  multiple of three written as a power of ten (:func:`sci`, ``2.34×10⁶ N/m``); an interval shares its median's
  exponent and gains digits only when its ends would otherwise read the same
  (``2.340×10⁶ N/m (2.339×10⁶–2.342×10⁶)``);
* any other number: four significant digits without exponent between 0.001 and 10⁶ (:func:`num`);
* intervals as ``median (low–high)`` with an en dash, never a Python list; a missing number as ``—``.

Layer 0: plain Python, no numpy needed (numpy scalars are accepted as numbers).
"""

from __future__ import annotations

import math

__all__ = ["num", "sci", "sci_parts", "parse", "mm", "length_mm", "lengths_mm", "rpm", "hz", "hz_range", "quantity",
           "width", "percent", "MISSING", "superscript"]

#: How a missing or non-finite number reads.
MISSING = "—"

_SUPERSCRIPT = str.maketrans("0123456789-", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻")


def superscript(n: int) -> str:
    """``n`` in superscript digits (``6`` -> ``⁶``, ``-3`` -> ``⁻³``)."""
    return str(int(n)).translate(_SUPERSCRIPT)


def _finite(x) -> float | None:
    if x is None or isinstance(x, bool):
        return None
    try:
        x = float(x)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def _fixed(x: float, decimals: int) -> str:
    text = f"{x:.{max(decimals, 0)}f}"
    return "0" if text.lstrip("-").strip("0.") == "" else text


def num(x, digits: int = 4) -> str:
    """A number for people: ``digits`` significant digits, trailing zeros dropped, no exponent between
    0.001 and 10⁶, integers as integers, an engineering power of ten outside; ``—`` if missing."""
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int):
        return str(x)
    if hasattr(x, "dtype") and getattr(x.dtype, "kind", "") in "iu":  # numpy integer
        return str(int(x))
    v = _finite(x)
    if v is None:
        return MISSING
    if v == 0:
        return "0"
    if 1e-3 <= abs(v) < 1e6:
        decimals = max(digits - 1 - int(math.floor(math.log10(abs(v)))), 0)
        text = f"{v:.{decimals}f}"
        return text.rstrip("0").rstrip(".") if "." in text else text
    mantissa, _, power = sci(v, digits).partition("×")
    if "." in mantissa:
        mantissa = mantissa.rstrip("0").rstrip(".")
    return f"{mantissa}×{power}"


def _exponent3(v: float) -> int:
    """The multiple of three at or below the decimal exponent of ``v`` (0 for 0)."""
    if v == 0:
        return 0
    e = int(math.floor(math.log10(abs(v))))
    return 3 * (e // 3)


def sci(x, digits: int = 3, lo=None, hi=None, unit: str = "") -> str:
    """A stiffness-like number in engineering form: ``2.34×10⁶`` (plain between 0.01 and 1000).

    Parameters
    ----------
    x : float, the number (the median when ``lo``/``hi`` are given); ``—`` if missing
    digits : int, significant digits of ``x``
    lo, hi : float, optional
        Interval ends, written with ``x``'s exponent and with more decimals only when the ends would
        otherwise read the same: ``2.340×10⁶ N/m (2.339×10⁶–2.342×10⁶)``.
    unit : str, appended after the median (``"N/m"``)
    """
    v = _finite(x)
    tail = f" {unit}" if unit else ""
    if v is None:
        return MISSING + tail if unit and lo is None else MISSING
    mid, a, b = sci_parts(v, lo, hi, digits)
    text = mid + tail
    if a != MISSING and b != MISSING:
        text += f" ({a}–{b})"
    return text


def sci_parts(x, lo=None, hi=None, digits: int = 3) -> tuple[str, str, str]:
    """``x``, ``lo`` and ``hi`` in :func:`sci`'s form with one exponent and one number of decimals (the columns of
    a table of medians and interval ends); ``—`` for a missing one."""
    v, a, b = _finite(x), _finite(lo), _finite(hi)
    ref = v if v is not None else next((y for y in (a, b) if y is not None), None)
    if ref is None:
        return MISSING, MISSING, MISSING
    e = 0 if ref == 0 or 0.01 <= abs(ref) < 1000 else _exponent3(ref)
    m = ref / 10.0 ** e
    lead = int(math.floor(math.log10(abs(m)))) if m else 0
    decimals = max(digits - 1 - lead, 0)
    if a is not None and b is not None and b > a:
        width = (b - a) / 10.0 ** e
        decimals = min(max(decimals, int(math.ceil(-math.log10(width / 2.0)))), decimals + 3)
    power = "" if e == 0 else f"×10{superscript(e)}"

    def one(y):
        return MISSING if y is None else _fixed(y / 10.0 ** e, decimals) + power

    return one(v), one(a), one(b)


def parse(text: str) -> float:
    """The number a human output wrote (``2.34×10⁶``, no unit): the inverse of :func:`sci` and :func:`num`."""
    mantissa, _, power = str(text).strip().partition("×10")
    digits = power.translate(str.maketrans("⁰¹²³⁴⁵⁶⁷⁸⁹⁻", "0123456789-"))
    return float(mantissa) * (10.0 ** int(digits) if digits else 1.0)


def mm(x_m, lo=None, hi=None) -> str:
    """A length or depth in metres as mm: ``0.164 mm``; ``0.00039 mm`` below 0.01 mm (two significant digits).

    With ``lo``/``hi`` (metres) the interval follows in the same decimals: ``0.164 mm (0.150–0.171)``.
    """
    v = _finite(x_m)
    if v is None:
        return f"{MISSING} mm"
    ends = [e * 1e3 for e in (_finite(lo), _finite(hi)) if e is not None]
    values = [1e3 * v, *ends]
    smallest = min((abs(u) for u in values if u != 0), default=1.0)
    decimals = 3 if smallest >= 0.01 else min(1 - int(math.floor(math.log10(smallest))), 9)
    text = f"{_fixed(1e3 * v, decimals)} mm"
    if len(ends) == 2:
        text += f" ({_fixed(ends[0], decimals)}–{_fixed(ends[1], decimals)})"
    return text


def length_mm(x_m) -> str:
    """A clamping or tool length in metres as mm, as a person gives it: ``25 mm``, ``32.5 mm``."""
    v = _finite(x_m)
    return f"{MISSING} mm" if v is None else f"{num(round(1e3 * v, 6), 4)} mm"


def lengths_mm(values_m) -> str:
    """Several lengths in metres: ``25, 30 and 40 mm``."""
    texts = [num(round(1e3 * float(v), 6), 4) for v in values_m]
    if not texts:
        return MISSING
    body = texts[0] if len(texts) == 1 else ", ".join(texts[:-1]) + " and " + texts[-1]
    return f"{body} mm"


def rpm(x, unit: bool = True) -> str:
    """A spindle speed in whole rpm: ``13647 rpm`` (``—`` if missing)."""
    v = _finite(x)
    text = MISSING if v is None else f"{v:.0f}"
    return f"{text} rpm" if unit else text


def _hz_decimals(lo: float | None, hi: float | None) -> int:
    """Decimals that show an interval's width with about two significant digits (0 to 2)."""
    if lo is None or hi is None or hi <= lo:
        return 1
    return int(min(max(1 - math.floor(math.log10(hi - lo)), 0), 2))


def hz(x, lo=None, hi=None, unit: bool = True) -> str:
    """A frequency with the digits its interval justifies: ``859.89 Hz (859.85–859.94)``; one decimal alone."""
    v, a, b = _finite(x), _finite(lo), _finite(hi)
    d = _hz_decimals(a, b)
    text = MISSING if v is None else f"{v:.{d}f}"
    if unit:
        text += " Hz"
    if a is not None and b is not None:
        text += f" ({a:.{d}f}–{b:.{d}f})"
    return text


def hz_range(lo, hi) -> str:
    """A frequency interval alone, in the digits its width justifies: ``859.85–859.94`` (no unit)."""
    a, b = _finite(lo), _finite(hi)
    if a is None or b is None:
        return MISSING
    d = _hz_decimals(a, b)
    return f"{a:.{d}f}–{b:.{d}f}"


#: Units written in engineering form by :func:`quantity` (stiffness, damping, pressure-like coefficients).
_ENGINEERING = ("N/m", "N m/rad", "N s/m", "N m s/rad", "Pa", "N/m^2", "m/N", "rad/(N m)", "1/m")


def quantity(x, unit: str, lo=None, hi=None) -> str:
    """Any physical value (SI ``unit``) the way the policy writes it; an interval in the same digits.

    ``m`` -> mm (:func:`mm`), ``Hz`` -> :func:`hz`, ``rpm`` -> :func:`rpm`, stiffness and damping units ->
    :func:`sci`, ``1`` (dimensionless) and others -> :func:`num` with three significant digits.
    """
    if unit == "m":
        return mm(x, lo, hi)
    if unit == "Hz":
        return hz(x, lo, hi)
    if unit == "rpm":
        return rpm(x)
    if unit in _ENGINEERING:
        return sci(x, 3, lo, hi, unit)
    tail = "" if unit in ("1", "", None) else f" {unit}"
    text = num(x, 3) + tail
    if _finite(lo) is not None and _finite(hi) is not None:
        text += f" ({num(lo, 3)}–{num(hi, 3)})"
    return text


def width(x, unit: str) -> str:
    """A width or difference of a quantity (no interval of its own): mm for metres, three significant digits for
    Hz (a width of 2.345 Hz is ``2.35 Hz``, not rounded to the decimals of a frequency), engineering form for
    stiffness."""
    if unit == "m":
        return mm(x)
    if unit in _ENGINEERING:
        return sci(x, 3, unit=unit)
    tail = "" if unit in ("1", "", None) else f" {unit}"
    return num(x, 3) + tail


def percent(x_rel, digits: int = 2) -> str:
    """A fraction as a percentage: ``0.0024`` -> ``0.24 %``."""
    v = _finite(x_rel)
    return f"{MISSING} %" if v is None else f"{num(100.0 * v, digits)} %"
