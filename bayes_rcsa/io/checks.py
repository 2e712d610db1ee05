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
from typing import Iterable, Sequence

import numpy as np

from .. import messages
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
    "SWAP_IMAG_POSITIVE",
    "SENSITIVITY_FACTOR",
    "FLANGE_CROSS_MIN",
    "RESONANCE_PHASE_DROP_DEG",
    "RESONANCE_PEAK_RISE",
    "sensitivity_factor",
    "spindle_block_problem",
    "check_spindle_block",
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
# |H|-weighted share of lines with Im h > 0 above which a one-signed real part with a real-dominated peak is read
# as swapped columns (the imaginary column then holds the old, sign-changing real part: 40-75 % on the example
# and bench files).  A passive file keeps about 1 % there, so a weak resonance on a large real background (a
# flange's p below or above its modes) is not mistaken for a swap.
SWAP_IMAG_POSITIVE = 0.2
# A measured amplitude off by a near-constant factor (sensor sensitivity, a calibration entered wrongly) is named
# when the ratio |H_measured| / |H_model| at the fitted parameters lies beyond this factor (either way) ...
SENSITIVITY_FACTOR = 2.5
# ... and stays within this spread (10 %-90 % quantile ratio of the |H_model|-weighted lines near the model's
# peaks): a fit that matches the shape but not the level.  A good fit gives 1.00 with a spread of ~1.05;
# a wrong contact or a missing effect moves the peak, which spreads the ratio over orders of magnitude.
SENSITIVITY_SPREAD = 1.5
#: Smallest ratio median |p| / median |h| of a flange block accepted: p (rad/(N m)) is h (m/N) divided by a
#: length squared of the order of the spindle nose (observed 1e2-5e3 on the bench, rotor and example files);
#: below 1 the two columns hold each other's data.
FLANGE_P_OVER_H_MIN = 1.0
#: Smallest (median |l|)^2 / (median |h| median |p|) of a flange block whose |l| is also below |h|: near a mode
#: the block is nearly rank one, so |l| is close to the geometric mean of |h| and |p| (0.5-1 on the bench and
#: example files).  A block with h and l/n exchanged has |l| < |h| and this ratio near (|h|/|l|)^2 |h|/|p|,
#: about 1e-3; reciprocity and passivity still hold, so only the magnitudes tell.
FLANGE_CROSS_MIN = 0.1
# The imaginary 2x2 block of a passive point block is negative semi-definite: (Im l)^2 <= Im h Im p.  Refused
# when |Im l| exceeds twice sqrt(Im h Im p) on more than half of the |l|-weighted lines (a model block stays
# below 1.0, noise does not double it where the signal is strong).
DEFINITENESS_FACTOR = 2.0


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
      like in the real column; and the imaginary column is not one-signed (more than
      :data:`SWAP_IMAG_POSITIVE` of the |H|-weighted lines have Im h > 0, which the old real part
      gives and a passive file does not: a weak resonance on a large one-signed real background,
      e.g. a flange's p, is valid).
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
    # A passive imaginary part is one-signed (Im h <= 0); after a swap the imaginary column holds the old real
    # part, which changes sign at every resonance (or is positive below it).  Without that, a one-signed real part
    # with a real-dominated peak is a weak resonance on a large real background (a flange's p), not a swap.
    if edge <= k < v.size - edge and abs(s) < 0.5 and frac_im_pos > SWAP_IMAG_POSITIVE:
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
        messages.warn(
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
    if mod.shape[0] == 1 and not causes:
        factor = sensitivity_factor(m, mod[0])
        if factor is not None:
            causes.append(sensitivity_cause(factor))
    return "; ".join(causes) if causes else None


def sensitivity_factor(measured, model) -> float | None:
    """The near-constant factor between a measured FRF and the fitted model's, or ``None``.

    Parameters
    ----------
    measured, model : (n_freq,) complex
        The measurement and the model at the fitted parameters, on the same lines.

    Returns
    -------
    float or None
        The |H_model|-weighted median of |H_measured| / |H_model| over the lines near the model's peaks
        (|H_model| >= 30 % of its largest value) when it lies beyond :data:`SENSITIVITY_FACTOR` either way
        and its 10 %-90 % spread stays within :data:`SENSITIVITY_SPREAD`: the fit matches the shape (the
        resonance is where it is measured) but not the level, which a wrong sensor sensitivity or
        calibration factor gives and no contact stiffness or damping can.  ``None`` otherwise.
    """
    m = np.abs(np.asarray(measured, dtype=complex).ravel())
    h = np.abs(np.asarray(model, dtype=complex).ravel())
    if m.size != h.size or m.size < 3 or not np.all(np.isfinite(h)) or not h.max() > 0:
        return None
    near = (h >= 0.3 * h.max()) & (m > 0)
    if near.sum() < 3:
        return None
    ratio = np.log(m[near] / h[near])
    w = h[near] / h[near].sum()
    order = np.argsort(ratio)
    cum = np.cumsum(w[order])

    def q(level):
        return float(ratio[order][min(int(np.searchsorted(cum, level)), ratio.size - 1)])

    median, spread = math.exp(q(0.5)), math.exp(q(0.9) - q(0.1))
    if spread > SENSITIVITY_SPREAD or 1 / SENSITIVITY_FACTOR <= median <= SENSITIVITY_FACTOR:
        return None
    return median


def sensitivity_cause(factor: float) -> str:
    """The likely-cause text of a near-constant amplitude factor (see :func:`sensitivity_factor`)."""
    shown = f"{factor:.3g}" if factor >= 1 else f"1/{1 / factor:.3g}"
    return (f"the measured |H| is {shown} x the fitted model's at every line near the resonance (a near-constant "
            f"factor: the shape fits, the level does not): sensor sensitivity / calibration factor ≈ {shown} "
            "(check the accelerometer's and the hammer's sensitivity settings of the export)")


def _flange_block_problems(block) -> list[str]:
    """What makes ``block`` no flange point block (empty when it is one); the checks of :func:`check_spindle_block`."""
    b = np.asarray(block)
    h, l, n, p = b[:, 0, 0], b[:, 0, 1], b[:, 1, 0], b[:, 1, 1]
    out = []
    for name, v in (("h", h), ("p", p)):
        why = passivity_problem(v)
        if why is not None:
            out.append(f"{name}: {why}")
    if reciprocity_error(b) > RECIPROCITY_WARN:
        out.append("l and n differ")
    mh, mp = float(np.median(np.abs(h))), float(np.median(np.abs(p)))
    if not mh > 0:
        out.append("h is zero")
    elif 0 < mp < FLANGE_P_OVER_H_MIN * mh:  # p = 0: a block without rotations (translation only) is valid
        out.append(f"median |p| = {mp:.3g} is below median |h| = {mh:.3g}")
    ml = float(np.median(np.abs(0.5 * (l + n))))
    if 0 < ml < mh and mp > 0 and ml ** 2 < FLANGE_CROSS_MIN * mh * mp:  # l = 0: a block without coupling
        out.append(f"median |l| = {ml:.3g} is below median |h| = {mh:.3g} and far below sqrt(|h| |p|) = "
                   f"{math.sqrt(mh * mp):.3g}")
    cross = 0.5 * (l + n).imag
    bound = np.sqrt(np.clip(h.imag * p.imag, 0.0, None))
    w = _weights(0.5 * (l + n))
    too_big = float(np.sum(w[np.abs(cross) > DEFINITENESS_FACTOR * bound]))
    if too_big > 0.5:
        out.append(f"|Im l| > {DEFINITENESS_FACTOR:g} sqrt(Im h Im p) on {100 * too_big:.0f} % of the |l|-weighted "
                   "lines")
    return out


_ENTRY_INDEX = {"h": (0, 0), "l": (0, 1), "n": (1, 0), "p": (1, 1)}


def spindle_block_problem(block) -> str | None:
    """The likely column permutation of a spindle flange block that is not a point block as read, or ``None``.

    A flange point block ``[[h, l], [n, p]]`` is passive (Im h <= 0, Im p <= 0 and the imaginary 2x2 block
    negative semi-definite), reciprocal (l = n) and, in SI units, ordered |h| < |l| < |p| numerically (h in
    m/N, l in 1/N, p in rad/(N m): each step divides by a length of the order of the spindle nose, so p
    exceeds h by 1e2-1e4).  When the block as read breaks one of these and some other assignment of its four
    columns to h, l, n, p satisfies all of them, that permutation is the likely mistake and is named.

    Parameters
    ----------
    block : (n_freq, 2, 2) complex

    Returns
    -------
    str or None
        e.g. ``"the h/l/n/p columns look permuted: read as h = p_*, p = h_* ..."``; ``None`` when the block
        is a point block as read, or when no permutation makes it one (the individual checks then name the
        cause).
    """
    import itertools

    b = np.asarray(block)
    found = _flange_block_problems(b)
    if not found:
        return None
    names = ("h", "l", "n", "p")
    for perm in itertools.permutations(names):
        if perm == names or perm == ("h", "n", "l", "p"):
            continue
        # perm[k]: the column read as names[k]
        cand = np.empty_like(b)
        for target, source in zip(names, perm):
            cand[(slice(None), *_ENTRY_INDEX[target])] = b[(slice(None), *_ENTRY_INDEX[source])]
        if _flange_block_problems(cand):
            continue
        moves = ", ".join(f"{t} = {s}_real/{s}_imag" for t, s in zip(names, perm) if t != s)
        return (f"the h/l/n/p columns look permuted ({found[0]}): read as {moves} the block is passive, reciprocal "
                "and ordered |h| < |l| < |p| as a flange block is (h in m/N is 1e2-1e4 x smaller than p in "
                "rad/(N m)); check the column headers")
    return None


def check_spindle_block(block, what: str) -> None:
    """Refuse (:class:`DataError`) a flange block whose columns are permuted or that is no passive point block.

    First :func:`spindle_block_problem` (a permutation of the h/l/n/p columns, named), then the checks that
    need no permutation to explain them: h and p passive (:func:`check_passive`), l = n
    (:func:`check_reciprocal`, which warns between 10 and 50 %), |p| > |h| and a negative semi-definite
    imaginary block.

    Parameters
    ----------
    block : (n_freq, 2, 2) complex ``[[h, l], [n, p]]``
    what : str
        The file, for the message.
    """
    perm = spindle_block_problem(block)
    if perm is not None:
        raise DataError(f"{what}: {perm}")
    b = np.asarray(block)
    check_passive(b[:, 0, 0], f"{what}: h (h_real, h_imag)")
    check_passive(b[:, 1, 1], f"{what}: p (p_real, p_imag)")
    check_reciprocal(b, f"{what}: l and n")
    mh, mp = float(np.median(np.abs(b[:, 0, 0]))), float(np.median(np.abs(b[:, 1, 1])))
    if 0 < mp < FLANGE_P_OVER_H_MIN * mh:
        raise DataError(f"{what}: median |p| = {mp:.3g} rad/(N m) is below median |h| = {mh:.3g} m/N; a flange "
                        "block has p 1e2-1e4 x larger than h numerically (1/length^2): h and p columns swapped, or "
                        "a column in other units?")
    for problem in _flange_block_problems(b):
        if problem.startswith("median |l|"):
            raise DataError(f"{what}: the h and l/n columns look swapped: {problem}; a flange block has |h| < |l| < "
                            "|p| numerically (h in m/N, l in 1/N, p in rad/(N m)) and |l| near sqrt(|h| |p|); check "
                            "the column headers")
        if problem.startswith("|Im l|"):
            raise DataError(f"{what}: not a passive point block: {problem} (the imaginary 2x2 block of a passive "
                            "point block is negative semi-definite): l and n in other units, or taken from another "
                            "block?")


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
    # a bump is no resonance: across a mode the phase of a receptance falls by 90 deg within its half-power band
    # (still by more than 50 deg over a band as narrow as +-2.5 % about a 5 %-damped mode), and |H| at the peak
    # stands out from the band's ends; a bump of a weak neighbouring mode does neither
    phase = np.degrees(np.unwrap(np.angle(np.asarray(values))))
    drop = float(np.max(np.maximum.accumulate(phase) - phase))
    rise = float(v[k] / max(v[0], v[-1]))
    if drop < RESONANCE_PHASE_DROP_DEG and rise < RESONANCE_PEAK_RISE:
        return (f"no resonance inside its band {f[0]:g}-{f[-1]:g} Hz: its largest |H| ({f[k]:g} Hz) is only "
                f"{rise:.2f} x the band's ends and the phase falls by {drop:.0f} deg (a resonance: about 90 deg or more), "
                "so the file cannot determine the contact (measure over a band that holds the first tool mode)")
    return None


#: Smallest phase drop (deg) across a tool-point band that holds a resonance (:func:`resonance_problem`).
RESONANCE_PHASE_DROP_DEG = 45.0
#: Peak |H| over the larger band-end |H| below which a band without that phase drop holds no resonance.
RESONANCE_PEAK_RISE = 1.5


#: Relative difference of the dominant natural frequencies of X and Y tool-point FRFs beyond which they are said
#: to come from different clamping lengths: X and Y of one clamping differ by well under 1 % on a symmetric tool
#: and a few per cent on an asymmetric spindle, while 5 mm of clamping length moves the tool mode by 10 % or more.
XY_PEAK_TOLERANCE = 0.08
#: Ratio of the peak |H| of X and Y tool-point FRFs beyond which a sensitivity or unit error is suspected: the two
#: directions of one tool differ by tens of per cent (damping, spindle anisotropy), a wrong sensitivity by 3-1000x.
XY_AMPLITUDE_RATIO = 3.0


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
    ax, ay = float(np.max(np.abs(vx))), float(np.max(np.abs(vy)))
    if ax > 0 and ay > 0 and max(ax, ay) / min(ax, ay) > XY_AMPLITUDE_RATIO:
        big = name_x if ax > ay else name_y
        return [f"the peak |H| of {name_x} ({ax:.3g} m/N) and {name_y} ({ay:.3g} m/N) differ by a factor "
                f"{max(ax, ay) / min(ax, ay):.3g} (X and Y of one tool stay within a factor of 2): a sensor "
                f"sensitivity or unit error in {big}?"]
    return []


def warn_all(lines: Iterable[str]) -> None:
    """Issue each line as a :class:`DataWarning` (recorded in the open warning logs first: :func:`messages.warn`)."""
    for msg in lines:
        messages.warn(msg, DataWarning, stacklevel=3)
