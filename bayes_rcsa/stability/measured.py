"""Measured tool-point FRFs and their random error: realisations for ``lobes --measured-x/--measured-y``.

A direction is given by one or more files (comma-separated; a UFF58 file may
hold several FRF records).  Its uncertainty comes from one of two sources:

Coherence and averages (one measurement)
    Bendat & Piersol (Random Data, 4th ed., sec. 9.2.4-9.2.5): an H1 estimate
    averaged over ``n`` impacts with ordinary coherence γ² has the normalised
    random errors

        ε(|Ĥ|) = sqrt(1 - γ²) / (|γ| sqrt(2 n))         (relative magnitude)
        σ(φ̂)  = ε(|Ĥ|)                                  (phase, rad)

    to first order, i.e. a circular complex Gaussian error of total variance
    |Ĥ|² (1 - γ²)/(n γ²) (the model the synthetic bench uses, docs/synthetic.md).
    Realisation d of the FRF is ``G_d = Ĥ (1 + ε (z1 + i z2))`` with standard
    normal z1 (magnitude, in phase with Ĥ) and z2 (phase, in quadrature); the
    coherence is floored at :data:`COHERENCE_FLOOR` so that a line with γ² = 0
    stays finite.

Repeated hits (R >= 2 files or records)
    The mean m_f of the hits and, per line, the 2 x 2 covariance S_f of
    (Re, Im) over the hits (R - 1 degrees of freedom).  With few hits S_f is
    too noisy to use line by line, so it is shrunk towards an isotropic target
    T_f = (t_f / 2) I whose total variance t_f is tr S pooled over the
    ±:data:`POOL_HALF_WIDTH` neighbouring lines (conjugate inverse-Wishart
    update, prior weight ν0 = :data:`PRIOR_REPEATS` pseudo-hits):

        Σ_f = (ν0 T_f + (R - 1) S_f) / (ν0 + R - 1)

    (weight of the target 0.8 with 2 hits, 0.67 with 3, 0.17 with 21).  The
    uncertainty of the mean is Σ_f / R; realisation d is
    ``G_d = m + chol(Σ_f / R) z_d``.  When the hits also carry coherence and
    averages, the spread between them is compared with the coherence-derived
    error (median over lines of sqrt(tr Σ_f / σ²_coh,f)); outside
    [1/:data:`DISAGREEMENT_FACTOR`, :data:`DISAGREEMENT_FACTOR`] the command
    warns (the hits may not be repeats of one setup).  The band uses the hits.

Neither (one file, no coherence or no number of averages): the FRF is used as
it is and the lobes are deterministic; the output says so in one line.  A
coherence column without a number of averages is not refused (older campaigns
and analyser exports often omit the count) but WARNED about: the coherence
cannot be turned into an error without ``n``, so the warning states the
assumption used -- the FRF is treated as exact, the lobes are deterministic --
and how to get the measurement's uncertainty (``--averages N`` or a
``# averages = N`` header line).  The bundled example files carry that header
(5 averages, as their bench made them), so they raise no warning.  Deterministic
lobes from files that do have a random-error model are asked for explicitly
(``exact=True``, ``lobes --deterministic``): the FRF, or the mean of the
hits, is then used as it is, without a warning.

The number of averages comes from ``--averages N`` or from a header line of
the file: ``# averages = N`` (also ``n_averages``, ``:`` instead of ``=``) in
a CSV file, ``averages=N`` in an ID line of a UFF58 record.  Everything is
vectorised over draws and lines (no Python loop over either).
"""

from __future__ import annotations

import hashlib
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import DataError, SetupError

__all__ = [
    "MeasuredDirection",
    "read_measured_direction",
    "bendat_piersol_error",
    "repeat_covariance",
    "draw_measured_frf",
    "interpolate_lines",
    "COHERENCE_FLOOR",
    "PRIOR_REPEATS",
    "POOL_HALF_WIDTH",
    "DISAGREEMENT_FACTOR",
]

COHERENCE_FLOOR = 1e-6
PRIOR_REPEATS = 4.0
POOL_HALF_WIDTH = 5
DISAGREEMENT_FACTOR = 3.0
_AVERAGES_KEY = re.compile(r"^\s*#?\s*(?:n_)?averages\s*[=:]\s*(\S+)\s*$", re.IGNORECASE)
_AVERAGES_UFF = re.compile(r"(?:n_)?averages\s*[=:]\s*(\S+)", re.IGNORECASE)


@dataclass(frozen=True)
class MeasuredDirection:
    """One direction's measured FRF and its random-error model.

    Attributes
    ----------
    frequency_hz : (n_freq,) Hz
    mean : (n_freq,) complex, m/N, the measured FRF (mean of the hits)
    model : {"coherence", "repeats", "none"}
    files : list of str, the files (records as ``file[i]``)
    epsilon : (n_freq,) relative random error ε(|Ĥ|) (model "coherence"), else None
    chol_mean : (n_freq, 2, 2) lower Cholesky factor of the covariance of the mean of (Re, Im), (m/N)²
        (model "repeats"), else None
    averages : int or None, impacts averaged per file
    coherence_ratio : float or None, repeats' scatter / coherence-derived error (repeats with coherence)
    notes : list of str, warnings (one line each)
    has_coherence : bool, the file(s) carry a coherence column
    """

    frequency_hz: np.ndarray
    mean: np.ndarray
    model: str
    files: list
    epsilon: np.ndarray | None = None
    chol_mean: np.ndarray | None = None
    averages: int | None = None
    coherence_ratio: float | None = None
    notes: list = field(default_factory=list)
    has_coherence: bool = False

    def describe(self) -> dict:
        """JSON-able summary (no per-line arrays)."""
        out = {"model": self.model, "files": list(self.files), "averages": self.averages,
               "repeats": len(self.files)}
        if self.epsilon is not None:
            out["relative_error_median"] = float(np.median(self.epsilon))
        if self.chol_mean is not None:
            sd = np.sqrt(np.sum(self.chol_mean**2, axis=(1, 2)))
            out["relative_error_median"] = float(np.median(sd / np.maximum(np.abs(self.mean), 1e-300)))
        if self.coherence_ratio is not None:
            out["repeats_to_coherence_error_ratio"] = self.coherence_ratio
        return out


# ------------------------------------------------------------------------------ error models
def bendat_piersol_error(coherence, averages: int) -> np.ndarray:
    """Normalised random error of an averaged H1 FRF estimate, ε = sqrt(1 - γ²)/(|γ| sqrt(2 n)).

    Parameters
    ----------
    coherence : (n_freq,) ordinary coherence γ² in [0, 1] (floored at :data:`COHERENCE_FLOOR`)
    averages : int >= 1, n

    Returns
    -------
    (n_freq,) relative magnitude error (= phase standard deviation in rad)
    """
    if isinstance(averages, bool) or not isinstance(averages, (int, np.integer)) or averages < 1:
        raise SetupError(f"averages = {averages!r}: expected an integer >= 1")
    g2 = np.clip(np.asarray(coherence, dtype=float), COHERENCE_FLOOR, 1.0)
    return np.sqrt((1.0 - g2) / (2.0 * averages * g2))


def _pooled(values: np.ndarray, half: int) -> np.ndarray:
    """Moving mean over ±half lines (shorter windows at the ends), (n,)."""
    n = values.size
    c = np.concatenate([[0.0], np.cumsum(values)])
    i = np.arange(n)
    lo, hi = np.maximum(i - half, 0), np.minimum(i + half + 1, n)
    return (c[hi] - c[lo]) / (hi - lo)


def repeat_covariance(hits, prior_repeats: float = PRIOR_REPEATS, half_width: int = POOL_HALF_WIDTH):
    """Mean and shrunk per-line covariance of repeated hits.

    Parameters
    ----------
    hits : (R, n_freq) complex, m/N, R >= 2
    prior_repeats : float > 0, ν0, weight of the pooled isotropic target in pseudo-hits
    half_width : int >= 0, lines pooled on each side for the target

    Returns
    -------
    mean : (n_freq,) complex, m/N
    cov : (n_freq, 2, 2) (m/N)², shrunk covariance of one hit's (Re, Im)
    raw : (n_freq, 2, 2) (m/N)², the sample covariance S (R - 1 degrees of freedom)
    """
    h = np.asarray(hits, dtype=complex)
    if h.ndim != 2 or h.shape[0] < 2:
        raise SetupError(f"repeated hits: expected (R >= 2, n_freq) values, got shape {h.shape}")
    r = h.shape[0]
    mean = h.mean(axis=0)
    dev = np.stack([(h - mean).real, (h - mean).imag], axis=-1)  # (R, F, 2)
    raw = np.einsum("rfi,rfj->fij", dev, dev) / (r - 1)
    total = _pooled(raw[:, 0, 0] + raw[:, 1, 1], half_width)
    target = 0.5 * total[:, None, None] * np.eye(2)
    cov = (prior_repeats * target + (r - 1) * raw) / (prior_repeats + r - 1)
    return mean, cov, raw


def _chol2(cov: np.ndarray) -> np.ndarray:
    """Lower Cholesky factors of (n, 2, 2) symmetric positive semi-definite matrices, closed form."""
    a, b, c = cov[:, 0, 0], cov[:, 1, 0], cov[:, 1, 1]
    l11 = np.sqrt(np.maximum(a, 0.0))
    l21 = np.divide(b, l11, out=np.zeros_like(b), where=l11 > 0)
    l22 = np.sqrt(np.maximum(c - l21**2, 0.0))
    out = np.zeros_like(cov)
    out[:, 0, 0], out[:, 1, 0], out[:, 1, 1] = l11, l21, l22
    return out


def draw_measured_frf(direction: MeasuredDirection, n_draws: int, rng: np.random.Generator) -> np.ndarray:
    """Realisations of the true FRF given the measurement, (n_draws, n_freq) complex m/N.

    Model "none" returns the measured FRF once, (1, n_freq).  ``rng`` is consumed as
    one (n_draws, n_freq, 2) block of standard normals.
    """
    if direction.model == "none":
        return direction.mean[None, :].copy()
    z = rng.standard_normal((n_draws, direction.mean.size, 2))
    if direction.model == "coherence":
        return direction.mean * (1.0 + direction.epsilon * (z[..., 0] + 1j * z[..., 1]))
    e = np.einsum("fij,dfj->dfi", direction.chol_mean, z)
    return direction.mean + e[..., 0] + 1j * e[..., 1]


def interpolate_lines(values, frequency_hz, target_hz) -> np.ndarray:
    """Complex linear interpolation of (n_draws, n_freq) values onto ``target_hz`` (inside the band), batched."""
    f = np.asarray(frequency_hz, dtype=float)
    t = np.asarray(target_hz, dtype=float)
    j = np.clip(np.searchsorted(f, t, side="right"), 1, f.size - 1)
    w = (t - f[j - 1]) / (f[j] - f[j - 1])
    v = np.atleast_2d(values)
    return v[:, j - 1] * (1.0 - w) + v[:, j] * w


# ------------------------------------------------------------------------------ reading
def _averages_value(text: str, where: str) -> int:
    try:
        value = float(text)
    except ValueError:
        raise DataError(f"{where}: averages = {text!r}, expected a whole number >= 1") from None
    if not (math.isfinite(value) and value == int(value) and value >= 1):
        raise DataError(f"{where}: averages = {text!r}, expected a whole number >= 1 (impacts averaged per FRF)")
    return int(value)


def _csv_header_averages(path: Path) -> int | None:
    """``# averages = N`` from the comment lines of a CSV file (None when absent)."""
    raw = path.read_bytes()
    text = raw.decode("utf-8", errors="replace")
    for k, line in enumerate(text.splitlines(), start=1):
        if not line.lstrip().startswith("#"):
            continue
        m = _AVERAGES_KEY.match(line)
        if m:
            return _averages_value(m.group(1), f"{path}: line {k}")
    return None


def _uff_records(path: Path):
    """The FRF records of a universal file as (FRF, averages from its ID lines or None) pairs."""
    import pyuff  # lazy, like the reader

    from ..io.checks import check_passive
    from ..io.uff58 import read_frf_uff

    try:
        uff = pyuff.UFF(str(path))
        types = [int(t) for t in uff.get_set_types()]
        heads = [uff.read_sets(k, header_only=True) for k, t in enumerate(types) if t == 58]
    except Exception as exc:  # pyuff raises bare Exception for every problem; the reader names it precisely
        read_frf_uff(path)  # raises the reader's DataError
        raise DataError(f"{path}: not a readable universal file ({exc})") from exc
    heads = [h for h in heads if h.get("func_type") == 4]
    out = []
    for i, head in enumerate(heads or [None]):
        frf = read_frf_uff(path, index=i if len(heads) > 1 else None)
        check_passive(frf.values, frf.source)  # as read_frf does for point receptances
        n = None
        for key in ("id1", "id2", "id3", "id4", "id5"):
            m = _AVERAGES_UFF.search(str((head or {}).get(key, "")))
            if m:
                n = _averages_value(m.group(1), f"{frf.source}: {key}")
                break
        out.append((frf, n))
    return out


def _read_hits(spec: str, option: str):
    """(list of FRF, list of averages-or-None) for a comma-separated file list."""
    from ..io.frf import read_frf

    names = [s.strip() for s in str(spec).split(",")]
    if any(not s for s in names):
        raise SetupError(f"{option} {spec!r}: an empty file name in the list (FILE or FILE1,FILE2,...)")
    seen = {}
    frfs, averages = [], []
    for name in names:
        path = Path(name)
        key = path.resolve() if path.exists() else path
        if key in seen:
            raise SetupError(f"{option}: {name} is given twice; a file read twice is not a repeated hit "
                             "(give the files of separate hits)")
        seen[key] = name
        if path.suffix.lower() in (".uff", ".unv", ".uf"):
            for frf, n in _uff_records(path):
                frfs.append(frf)
                averages.append(n)
        else:
            frf = read_frf(path)  # every check of the reader (format, units, passivity)
            frfs.append(frf)
            averages.append(_csv_header_averages(path))
    return frfs, averages


def read_measured_direction(spec: str, averages: int | None, option: str = "--measured-x",
                            exact: bool = False) -> MeasuredDirection:
    """Read one direction's files and choose its random-error model (module notes).

    Parameters
    ----------
    spec : str, ``FILE`` or ``FILE1,FILE2,...`` (CSV or UFF58; a UFF58 file may hold several FRF records)
    averages : int or None, ``--averages`` (overrides a header key)
    option : str, option name used in messages
    exact : bool, use the FRF (the mean of the hits) as it is: model "none" whatever the files carry
        (every input check still applies)

    Returns
    -------
    MeasuredDirection

    Raises
    ------
    SetupError
        ``averages`` <= 0, a file named twice.
    DataError
        Unreadable files, repeats on different frequency lines, two hits holding identical values.
    """
    if averages is not None and (isinstance(averages, bool) or averages < 1):
        raise SetupError(f"--averages {averages!r}: expected a whole number >= 1 (impacts averaged per FRF)")
    frfs, header_n = _read_hits(spec, option)
    notes: list[str] = []
    f = frfs[0].frequency_hz
    for frf in frfs[1:]:
        if frf.frequency_hz.shape != f.shape or not np.allclose(frf.frequency_hz, f, rtol=1e-9, atol=0):
            raise DataError(f"{option}: {frf.source} ({frf.frequency_hz.size} lines, {frf.frequency_hz[0]:g}-"
                            f"{frf.frequency_hz[-1]:g} Hz) and {frfs[0].source} ({f.size} lines, {f[0]:g}-{f[-1]:g} "
                            "Hz) are on different frequency lines; repeated hits must share the analyser's lines")
    digests = {}
    for frf in frfs:
        d = hashlib.sha256(np.ascontiguousarray(frf.values).tobytes()).hexdigest()
        if d in digests:
            raise DataError(f"{option}: {frf.source} holds exactly the same FRF as {digests[d]}; a copy is not a "
                            "repeated hit (give the files of separate hits)")
        digests[d] = frf.source
    n = averages
    if n is None:
        found = sorted({v for v in header_n if v is not None})
        if len(found) > 1:
            raise DataError(f"{option}: the files give different numbers of averages {found}; give --averages N")
        n = found[0] if found else None
    elif any(v is not None and v != averages for v in header_n):
        notes.append(f"{option}: --averages {averages} overrides the files' header key "
                     f"({', '.join(str(v) for v in header_n if v is not None)})")
    has_coh = [frf.coherence is not None for frf in frfs]
    files = [frf.source for frf in frfs]
    if exact:
        mean = np.mean([frf.values for frf in frfs], axis=0) if len(frfs) >= 2 else frfs[0].values
        return MeasuredDirection(f, mean, "none", files, averages=n, notes=notes, has_coherence=all(has_coh))
    if len(frfs) >= 2:
        hits = np.stack([frf.values for frf in frfs])
        mean, cov, _ = repeat_covariance(hits)
        ratio = None
        if n is not None and all(has_coh):
            coh_var = np.mean([np.abs(frf.values) ** 2 * 2 * bendat_piersol_error(frf.coherence, n) ** 2
                               for frf in frfs], axis=0)
            tot = cov[:, 0, 0] + cov[:, 1, 1]
            ok = coh_var > 0
            if np.any(ok):
                ratio = float(np.median(np.sqrt(tot[ok] / coh_var[ok])))
                if not (1 / DISAGREEMENT_FACTOR <= ratio <= DISAGREEMENT_FACTOR):
                    notes.append(
                        f"{option}: the scatter between the {len(frfs)} hits is {ratio:.2g} x the random error their "
                        f"coherence and {n} averages imply (median over lines; tolerated factor "
                        f"{DISAGREEMENT_FACTOR:g}): " + ("the hits may not be repeats of one setup (re-clamped tool, "
                                                         "another point or direction)" if ratio > 1 else
                                                         "the coherence overstates the error") +
                        "; the band uses the hits' scatter")
        return MeasuredDirection(f, mean, "repeats", files, chol_mean=_chol2(cov / len(frfs)), averages=n,
                                 coherence_ratio=ratio, notes=notes, has_coherence=all(has_coh))
    frf = frfs[0]
    if frf.coherence is not None and n is not None:
        return MeasuredDirection(f, frf.values, "coherence", files, epsilon=bendat_piersol_error(frf.coherence, n),
                                 averages=n, notes=notes, has_coherence=True)
    if frf.coherence is None and averages is not None:
        notes.append(f"{option}: --averages {averages} given but {Path(frf.source).name} has no coherence: its "
                     "random error is unknown and these lobes are deterministic")
    elif frf.coherence is not None:  # n is None: the coherence alone does not give the error (module notes)
        notes.append(f"{option}: {Path(frf.source).name} has a coherence column but no number of averages; "
                     "assumed: no random error (the FRF is taken as exact, the lobes are deterministic); give "
                     "--averages N or a '# averages = N' header line for the measurement's uncertainty, or "
                     "--deterministic for exact-FRF lobes")
    return MeasuredDirection(f, frf.values, "none", files, averages=n, notes=notes,
                             has_coherence=frf.coherence is not None)
