"""Measured receptance data: tool-point FRFs and 2x2 point blocks (spindle flange)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import DataError, ModelError

__all__ = ["FRF", "PointReceptance"]


def _check_frequency(frequency_hz: np.ndarray, source: str) -> np.ndarray:
    f = np.asarray(frequency_hz, dtype=float)
    if f.ndim != 1 or f.size == 0:
        raise DataError(f"{source}: frequency_hz must be a non-empty 1-D array")
    if not np.all(np.isfinite(f)):
        raise DataError(f"{source}: frequency_hz contains NaN or inf")
    if np.any(f <= 0):
        raise DataError(f"{source}: frequency_hz must be > 0 Hz (found {f[f <= 0][0]!r})")
    if np.any(np.diff(f) <= 0):
        i = int(np.argmax(np.diff(f) <= 0))
        raise DataError(f"{source}: frequency_hz must be strictly increasing (line {i + 2}: {f[i + 1]!r} after {f[i]!r})")
    return f


@dataclass(frozen=True)
class FRF:
    """A single-input single-output receptance (e.g. a tool-point FRF).

    Attributes
    ----------
    frequency_hz : (n_freq,) Hz, strictly increasing, > 0
    values : (n_freq,) complex, m/N (displacement per force)
    coherence : (n_freq,) in [0, 1] or None
    source : str
        File name or description, used in messages.
    """

    frequency_hz: np.ndarray
    values: np.ndarray
    coherence: np.ndarray | None = None
    source: str = "<frf>"

    def __post_init__(self) -> None:
        f = _check_frequency(self.frequency_hz, self.source)
        v = np.asarray(self.values, dtype=complex)
        if v.shape != f.shape:
            raise DataError(f"{self.source}: {v.shape[0] if v.ndim else 0} values for {f.size} frequencies")
        if not np.all(np.isfinite(v)):
            raise DataError(f"{self.source}: receptance values contain NaN or inf")
        object.__setattr__(self, "frequency_hz", f)
        object.__setattr__(self, "values", v)
        if self.coherence is not None:
            c = np.asarray(self.coherence, dtype=float)
            if c.shape != f.shape or not np.all(np.isfinite(c)) or np.any((c < 0) | (c > 1)):
                raise DataError(f"{self.source}: coherence must be finite values in [0, 1], one per frequency")
            object.__setattr__(self, "coherence", c)

    @property
    def omega(self) -> np.ndarray:
        """(n_freq,) rad/s"""
        return 2 * np.pi * self.frequency_hz


@dataclass(frozen=True)
class PointReceptance:
    """A 2x2 point receptance block ``[[h, l], [n, p]]`` on a frequency grid.

    Attributes
    ----------
    frequency_hz : (n_freq,) Hz
    block : (n_freq, 2, 2) complex; h m/N, l 1/N, n rad/N, p rad/(N m)
    source : str
    """

    frequency_hz: np.ndarray
    block: np.ndarray
    source: str = "<receptance>"

    def __post_init__(self) -> None:
        f = _check_frequency(self.frequency_hz, self.source)
        b = np.asarray(self.block, dtype=complex)
        if b.shape != (f.size, 2, 2):
            raise DataError(f"{self.source}: receptance block shape {b.shape}, expected ({f.size}, 2, 2)")
        if not np.all(np.isfinite(b)):
            raise DataError(f"{self.source}: receptance values contain NaN or inf")
        object.__setattr__(self, "frequency_hz", f)
        object.__setattr__(self, "block", b)

    def interpolate(self, frequency_hz: np.ndarray) -> np.ndarray:
        """Linear interpolation of the complex block onto ``frequency_hz``.

        Raises
        ------
        ModelError
            If any requested frequency lies outside the stored range (no
            extrapolation).
        """
        f = np.asarray(frequency_hz, dtype=float)
        lo, hi = self.frequency_hz[0], self.frequency_hz[-1]
        # Half a part in 1e12 lets grids written as decimal text match the ends.
        tol = 1e-12 * hi
        if f.min() < lo - tol or f.max() > hi + tol:
            raise ModelError(
                f"{self.source}: requested frequencies {f.min():g}-{f.max():g} Hz lie outside the "
                f"file's range {lo:g}-{hi:g} Hz; refusing to extrapolate"
            )
        fc = np.clip(f, lo, hi)  # only absorbs the round-off tolerance checked above
        out = np.empty((f.size, 2, 2), dtype=complex)
        for i in range(2):
            for j in range(2):
                col = self.block[:, i, j]
                out[:, i, j] = np.interp(fc, self.frequency_hz, col.real) + 1j * np.interp(fc, self.frequency_hz, col.imag)
        return out
