"""Plausibility checks of measured receptances: passivity, reciprocity, units, campaign consistency.

Every measured FRF the toolkit reads goes through these checks (the
readers and :func:`bayes_rcsa.io.load_setup` call them), so that a file in
the other sign convention, with swapped columns, in mm/N, or listed twice is
refused or flagged *before* it produces a confident but wrong result.

Two principles keep them free of false alarms on real data:

- The data contract (docs/data-formats.md) says noise may push Im h above
  zero at lines far from resonance: such lines are data.  The checks
  therefore look at where the signal is, i.e. they weight every line by
  |H| and judge the dominant peak, where the signal-to-noise ratio is
  highest.
- Thresholds are chosen so that the defects they target (negated imaginary
  part, swapped real/imag columns, a factor of 1000, the same file twice)
  lie far beyond them, while hammer-test noise stays far below.

The functions are public so that later stages (e.g. the noise-scale check
of the identification) can name the same likely causes.
"""

from __future__ import annotations

import math
import warnings
from typing import Iterable, Sequence

import numpy as np

from ..errors import DataError, DataWarning

__all__ = [
    "passivity_problem",
    "check_passive",
    "reciprocity_error",
    "check_reciprocal",
    "check_magnitude",
    "likely_cause",
    "dominant_frequency",
    "check_campaign",
    "radians_problem",
    "xy_pair_warnings",
    "XY_PEAK_TOLERANCE",
    "resonance_problem",
    "MAX_RECEPTANCE",
    "MAX_FREQUENCY_HZ",
    "RECIPROCITY_WARN",
    "RECIPROCITY_REFUSE",
    "SCALE_REFUSE",
    "warn_all",
]

# |h| of 1 m/N (one metre per newton) is beyond any machine-tool structure by
# orders of magnitude; larger numbers are a unit or column error (or garbage).
MAX_RECEPTANCE = 1.0
# Hammer tests end below 50 kHz; 10 MHz leaves room for any structural test.
MAX_FREQUENCY_HZ = 1e7
# Relative difference ||l - n|| / ||(l + n)/2|| of a spindle block's
# cross terms.  Identification noise of a measured block stays at a few per
# cent; 10 % is suspicious, 50 % (e.g. n = 2 l, or n = -l) is a column,
# unit or sign mix-up.
RECIPROCITY_WARN = 0.10
RECIPROCITY_REFUSE = 0.50
# Ratio between the measured and modelled receptance scale beyond which the
# measurement is refused.  Contact stiffness and damping change the median
# |H| over a band by far less; mm/N instead of m/N is a factor 1000.
SCALE_REFUSE = 100.0


def _weights(values: np.ndarray) -> np.ndarray:
    w = np.abs(values)
    total = w.sum()
    return w / total if total > 0 else w


def passivity_problem(values) -> str | None:
    """Why a point receptance is clearly not passive, or ``None`` if it is acceptable.

    A passive point receptance has Im h <= 0 (convention x = Re{X e^{+iωt}}).
    Noise far from resonance may violate this and is accepted; only a clear
    violation where the signal is strong is reported.

    Parameters
    ----------
    values : (n_freq,) complex
        Point receptance (m/N for h, rad/(N m) for p; the check is unit-free).

    Returns
    -------
    str or None
        A short description of the likely cause: the other sign convention
        (imaginary part negated) or swapped real/imaginary columns.

    Notes
    -----
    Criteria (all |H|-weighted, so noise at small |H| does not count):

    - sign: more than half of the |H|-weighted lines have Im h > 0 and at
      the line of largest |H| the imaginary part carries more than half of
      |H| with a positive sign, or more than 75 % of the |H|-weighted lines
      have Im h > 0 (a sign-flipped resonant FRF has ~100 %, a clean one
      ~1 %);
    - swapped columns: the largest |H| is an interior resonance peak whose
      imaginary part is small (|Im h| < |h|/2; a passive resonance peak has
      Im h ~ -|h|) while more than 90 % of the |H|-weighted lines have a
      one-signed *real* part (negative: swapped; positive: swapped and the
      other sign convention), which is what a passive imaginary part looks
      like in the real column.
    """
    v = np.asarray(values, dtype=complex).ravel()
    if v.size == 0:
        return None
    mag = np.abs(v)
    k = int(np.argmax(mag))
    if mag[k] == 0:
        return None
    s = v[k].imag / mag[k]
    w = _weights(v)
    frac_im_pos = float(np.sum(w[v.imag > 0]))
    frac_re_neg = float(np.sum(w[v.real < 0]))
    if (s > 0.5 and frac_im_pos > 0.5) or frac_im_pos > 0.75:
        return (f"Im h > 0 where the signal is strong ({100 * frac_im_pos:.0f} % of the |H|-weighted lines, "
                f"Im h/|h| = {s:+.2f} at the largest peak): the imaginary part has the wrong sign, e.g. the file "
                "uses the e^{-iωt} convention (negate the imag column)")
    # Swapped columns keep |H| (and so the resonance peak) but move the passive, one-signed
    # imaginary part into the real column.  Only judged at an interior peak: a band that holds no
    # resonance (e.g. only the mass line above it) legitimately has a one-signed real part.
    edge = max(2, v.size // 100)
    if edge <= k < v.size - edge and abs(s) < 0.5:
        frac_re_pos = float(np.sum(w[v.real > 0]))
        if frac_re_neg > 0.9:
            return (f"the real part is negative on {100 * frac_re_neg:.0f} % of the |H|-weighted lines while the "
                    f"resonance peak has almost no imaginary part (Im h/|h| = {s:+.2f}): the real and imag columns "
                    "look swapped")
        if frac_re_pos > 0.9:
            return (f"the real part is positive on {100 * frac_re_pos:.0f} % of the |H|-weighted lines while the "
                    f"resonance peak has almost no imaginary part (Im h/|h| = {s:+.2f}): the real and imag columns "
                    "look swapped and the imaginary part has the wrong sign (e^{-iωt} convention?)")
    return None


def check_passive(values, what: str) -> None:
    """Raise :class:`DataError` if :func:`passivity_problem` finds a clear violation.

    Parameters
    ----------
    values : (n_freq,) complex
    what : str
        File and quantity for the message, e.g. ``"tip.csv"`` or ``"spindle_x.csv: h"``.
    """
    problem = passivity_problem(values)
    if problem is not None:
        raise DataError(f"{what}: not a passive point receptance: {problem}")


def check_magnitude(frequency_hz, values, what: str) -> None:
    """Refuse receptance magnitudes above :data:`MAX_RECEPTANCE` and frequencies above :data:`MAX_FREQUENCY_HZ`.

    Such numbers are finite but physically absurd; letting them through only
    moves the failure into overflow warnings deep inside the model.
    """
    f = np.asarray(frequency_hz, dtype=float)
    v = np.asarray(values)
    if f.size and f.max() > MAX_FREQUENCY_HZ:
        raise DataError(f"{what}: frequency {float(f.max())!r} Hz is implausible (expected <= {MAX_FREQUENCY_HZ:g} Hz)")
    mag = np.abs(v)
    if mag.size and mag.max() > MAX_RECEPTANCE:
        i = np.unravel_index(int(np.argmax(mag)), mag.shape)[0]
        raise DataError(
            f"{what}: |receptance| = {float(mag.max()):.3g} at {float(f[i]):g} Hz is implausible (expected "
            f"<= {MAX_RECEPTANCE:g} in SI units, e.g. m/N); wrong units or columns?"
        )


def reciprocity_error(block) -> float:
    """Relative difference of the cross terms of 2x2 point blocks, ||l - n|| / ||(l + n)/2||.

    Parameters
    ----------
    block : (n_freq, 2, 2) complex ``[[h, l], [n, p]]``

    Returns
    -------
    float
        0 for a reciprocal block; ``inf`` when l = -n (or both vanish unequally).
    """
    b = np.asarray(block)
    l, n = b[:, 0, 1], b[:, 1, 0]
    diff = float(np.linalg.norm(l - n))
    mean = float(np.linalg.norm(0.5 * (l + n)))
    if diff == 0:
        return 0.0
    return diff / mean if mean > 0 else math.inf


def check_reciprocal(block, what: str) -> float:
    """Refuse (:class:`DataError`) or warn (:class:`DataWarning`) on a non-reciprocal spindle block.

    A point block is reciprocal (l = n).  Beyond :data:`RECIPROCITY_REFUSE`
    the file is refused: that is no longer measurement noise but a column,
    unit or sign error, and coupling such a block makes the assembled model
    non-reciprocal, so the rotational contact stiffness would absorb the
    error silently (it runs to a prior bound).  Between
    :data:`RECIPROCITY_WARN` and that it warns: an inverse-RCSA flange block
    from noisy artifact tests can be this far off, and the user may still
    want to proceed.

    Returns
    -------
    float
        The relative error of :func:`reciprocity_error`.
    """
    err = reciprocity_error(block)
    b = np.asarray(block)
    if err > RECIPROCITY_REFUSE:
        l, n = b[:, 0, 1], b[:, 1, 0]
        hint = ""
        if np.linalg.norm(l + n) < 0.5 * np.linalg.norm(l - n):
            hint = " (n = -l: the slope or moment sign convention differs between the columns)"
        raise DataError(
            f"{what}: not reciprocal: ||l - n|| is {100 * err:.0f} % of ||(l + n)/2|| (a point block has l = n; "
            f"measurement noise stays far below {100 * RECIPROCITY_REFUSE:.0f} %){hint}; check the l_*/n_* columns"
        )
    if err > RECIPROCITY_WARN:
        warnings.warn(
            f"{what}: cross terms differ by {100 * err:.0f} % (||l - n|| / ||(l + n)/2||, reciprocal blocks have l = n); "
            "the rotational contact stiffness may absorb this", DataWarning, stacklevel=2)
    return err


def likely_cause(measured, model) -> str | None:
    """Name the likely cause when a measurement and the model disagree grossly, else ``None``.

    Parameters
    ----------
    measured : (n_freq,) complex
        Measured point receptance, m/N.
    model : (n_freq,) or (n_sets, n_freq) complex
        Modelled receptance on the same lines, m/N: one parameter set or
        several spanning the plausible range (e.g. the corners of the
        contact prior); the measured scale is compared with the range they
        cover.

    Returns
    -------
    str or None
        ``"... units ..."`` when the median |H| differs from every model
        set by more than :data:`SCALE_REFUSE` (e.g. a factor 1000: mm/N
        instead of m/N), or the sign/column problem found by
        :func:`passivity_problem`; ``None`` when neither applies.

    Notes
    -----
    The median of |H| over the lines is used because it is set by the
    off-resonance dynamic stiffness, which the contact parameters change
    far less than the peak height.
    """
    m = np.asarray(measured, dtype=complex).ravel()
    mod = np.atleast_2d(np.asarray(model, dtype=complex))
    causes = []
    sign = passivity_problem(m)
    if sign is not None:
        causes.append(sign)
    med_m = float(np.median(np.abs(m)))
    med_model = np.median(np.abs(mod), axis=1)
    med_model = med_model[np.isfinite(med_model) & (med_model > 0)]
    if med_m > 0 and med_model.size:
        lo, hi = float(med_model.min()), float(med_model.max())
        if med_m > SCALE_REFUSE * hi:
            ratio = med_m / hi
            unit = "mm/N instead of m/N (x 1000)" if ratio < 1e5 else "µm/N instead of m/N (x 1e6)"
            causes.append(f"the measured |H| is about {ratio:.3g} x the largest the model gives for any contact in the "
                          f"prior: probably {unit}")
        elif med_m < lo / SCALE_REFUSE:
            ratio = lo / med_m
            causes.append(f"the measured |H| is about 1/{ratio:.3g} of the smallest the model gives for any contact in "
                          "the prior: wrong units (expected m/N) or a scaled file")
    return "; ".join(causes) if causes else None


def dominant_frequency(frequency_hz, values, lo: float | None = None, hi: float | None = None) -> float:
    """Frequency (Hz) of the largest |H| within [lo, hi] (default: all lines)."""
    f = np.asarray(frequency_hz, dtype=float)
    v = np.abs(np.asarray(values))
    sel = np.ones(f.size, bool)
    if lo is not None:
        sel &= f >= lo
    if hi is not None:
        sel &= f <= hi
    if not sel.any():
        return math.nan
    return float(f[sel][int(np.argmax(v[sel]))])


def check_campaign(entries: Sequence[tuple[str, float, str, str, np.ndarray, np.ndarray]]) -> list[str]:
    """Consistency of a set of tool-point measurements; raise on duplicates, return warnings.

    Parameters
    ----------
    entries : sequence of (name, clamping_length, direction, tool, frequency_hz, values)
        One per measurement; ``name`` is used in messages (file name).

    Returns
    -------
    list of str
        Warnings: the same data for different directions or tools, and
        dominant natural frequencies that do not rise with clamping length.
        (A longer clamping length means a shorter overhang, hence a stiffer
        tool and a higher first tool mode; measured frequencies falling with
        clamping length point at swapped or mislabelled lengths.)

    Raises
    ------
    DataError
        Identical data listed at two clamping lengths, or twice for the same
        configuration (the likelihood would count the measurement twice).
    """
    out: list[str] = []
    for i in range(len(entries)):
        for j in range(i):
            a, b = entries[j], entries[i]
            if a[4].shape == b[4].shape and np.array_equal(a[4], b[4]) and np.array_equal(a[5], b[5]):
                if a[1] != b[1]:
                    raise DataError(
                        f"{b[0]} (clamping_length {b[1]!r} m) holds the same data as {a[0]} (clamping_length "
                        f"{a[1]!r} m): one measurement listed at two clamping lengths")
                if a[2:4] == b[2:4]:
                    raise DataError(f"{b[0]} and {a[0]}: the same measurement is listed twice for clamping_length "
                                    f"{a[1]!r} m, direction {a[2]!r}, tool {a[3]!r}")
                out.append(f"{b[0]} holds the same data as {a[0]} (direction {a[2]}/{b[2]}, tool {a[3]}/{b[3]}); "
                           "intended?")
    groups: dict[tuple[str, str], list[tuple[float, str, float, float]]] = {}
    for name, cl, direction, tool, f, v in entries:
        groups.setdefault((direction, tool), []).append((cl, name, f, v))
    for (direction, tool), items in groups.items():
        if len(items) < 2:
            continue
        # Compare peaks on the common frequency range only.
        lo = max(float(f[0]) for _, _, f, _ in items)
        hi = min(float(f[-1]) for _, _, f, _ in items)
        if not hi > lo:
            continue
        peaks = sorted((cl, name, dominant_frequency(f, v, lo, hi), float(np.median(np.diff(f))) if f.size > 1 else 0.0)
                       for cl, name, f, v in items)
        falls = []
        for (cl1, n1, f1, d1), (cl2, n2, f2, d2) in zip(peaks, peaks[1:]):
            # Tolerance: a couple of lines (peak picking on noisy data) and 1 % (a mode switch between close peaks).
            tol = max(2.0 * max(d1, d2), 0.01 * f1)
            if cl2 > cl1 and f2 < f1 - tol:
                falls.append(f"{f1:.1f} Hz ({n1}, {1e3 * cl1:g} mm) to {f2:.1f} Hz ({n2}, {1e3 * cl2:g} mm)")
        if falls:
            out.append(
                f"direction {direction}, tool {tool}: the dominant natural frequency falls from {'; from '.join(falls)} "
                "although a longer clamping length (shorter overhang) raises it: clamping lengths swapped or "
                "mislabelled?")
    return out


#: Tolerance of the 2π ratio between frequency ranges that marks a file in rad/s (analysers end their ranges on
#: round numbers; a 2π ratio within 4 % by chance is unlikely, and the dominant peaks must agree too).
RADIANS_TOLERANCE = 0.04


def radians_problem(name: str, frequency_hz, values, references: Sequence[tuple[str, np.ndarray, np.ndarray | None]]
                    ) -> str | None:
    """Why the frequency column of ``name`` looks like rad/s rather than Hz, or ``None``.

    Parameters
    ----------
    name : file name for the message
    frequency_hz, values : the file's lines and receptance
    references : (name, frequency_hz, values or None) of files of the same campaign in Hz (the spindle
        receptance, the other measurements)

    Notes
    -----
    Rule: the last line of the file is 2π times the last line of a reference (within
    :data:`RADIANS_TOLERANCE`) and, when the reference has values, its dominant peak lies 4-9 times higher.
    """
    f = np.asarray(frequency_hz, dtype=float)
    if f.size < 2:
        return None
    two_pi = 2 * math.pi
    for ref_name, ref_f, ref_v in references:
        ref_f = np.asarray(ref_f, dtype=float)
        if ref_f.size < 2 or not ref_f[-1] > 0:
            continue
        if abs(f[-1] / ref_f[-1] / two_pi - 1) > RADIANS_TOLERANCE:
            continue
        if ref_v is not None:
            ratio = dominant_frequency(f, values) / dominant_frequency(ref_f, ref_v)
            if not 4.0 < ratio < 9.0:
                continue
        return (f"{name}: the frequencies look like rad/s, not Hz: the lines end at {f[-1]:.6g}, 2π times the "
                f"{ref_f[-1]:.6g} Hz of {ref_name} (divide the frequency column by 2π)")
    return None


def resonance_problem(frequency_hz, values) -> str | None:
    """Why a tool-point FRF holds no resonance to identify anything from, or ``None``.

    A file whose largest |H| lies at its first or last lines (e.g. one cut to a
    few lines below the first mode) has no resonance inside its band: the
    contact stiffness is not determined by it, and a "converged" posterior would
    only restate the prior.
    """
    v = np.abs(np.asarray(values))
    f = np.asarray(frequency_hz, dtype=float)
    n = v.size
    if n < 5:
        return f"only {n} frequency line(s): no resonance can be seen"
    k = int(np.argmax(v))
    edge = max(1, n // 100)
    if k < edge or k >= n - edge:
        where = "first" if k < edge else "last"
        return (f"no resonance inside its band {f[0]:g}-{f[-1]:g} Hz: the largest |H| is at its {where} line "
                f"({f[k]:g} Hz), so the file cannot determine the contact (measure over a band that holds the first "
                "tool mode)")
    return None


#: Relative difference of the dominant natural frequencies of X and Y tool-point FRFs beyond which they are said
#: to come from different clamping lengths: X and Y of one clamping differ by well under 1 % on a symmetric tool
#: and a few per cent on an asymmetric spindle, while 5 mm of clamping length moves the tool mode by 10 % or more.
XY_PEAK_TOLERANCE = 0.08


def xy_pair_warnings(name_x: str, name_y: str, frequency_hz, values_x, values_y) -> list[str]:
    """Warnings for the X and Y tool-point FRFs of one clamping (``lobes`` in measured mode).

    - the same data in both files (one file given twice: the lobes would assume a symmetric tool without
      saying so);
    - dominant natural frequencies more than :data:`XY_PEAK_TOLERANCE` apart (files of different clamping
      lengths or setups).
    """
    f = np.asarray(frequency_hz, dtype=float)
    vx, vy = np.asarray(values_x), np.asarray(values_y)
    if vx.shape == vy.shape and np.array_equal(vx, vy):
        return [f"{name_x} and {name_y} hold the same data: the same measurement given for X and Y? (the lobes then "
                "assume a tool that is equally stiff in both directions)"]
    px, py = dominant_frequency(f, vx), dominant_frequency(f, vy)
    if math.isfinite(px) and math.isfinite(py) and abs(px - py) > XY_PEAK_TOLERANCE * min(px, py):
        return [f"the dominant natural frequencies of {name_x} ({px:.1f} Hz) and {name_y} ({py:.1f} Hz) differ by "
                f"{100 * abs(px - py) / min(px, py):.0f} % (X and Y of one clamping stay within a few per cent): "
                "files of different clamping lengths or setups?"]
    return []


def warn_all(messages: Iterable[str]) -> None:
    """Issue each message as a :class:`DataWarning`."""
    for msg in messages:
        warnings.warn(msg, DataWarning, stacklevel=3)
