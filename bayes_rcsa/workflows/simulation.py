"""``simulate``: the predicted tool-point FRF of a set-up for given contact stiffness and damping.

>>> frf = bayes_rcsa.simulate("setup.toml", clamping_length=0.025, kx=2e6, ktheta=5e5)
>>> frf.save("tip_x_25mm.csv")

The same numbers as ``bayes-rcsa simulate SETUP --clamping-length 0.025
--kx 2e6 --ktheta 5e5 --out tip_x_25mm.csv``, which is this call and
:meth:`SimulatedFRF.save`.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np

from ..errors import DataError, SetupError
from ..messages import warning_log
from ..units import hz, length_mm, sci
from ..vocabulary import parameter_name
from .result import Result

__all__ = ["simulate", "SimulatedFRF"]


@dataclass
class SimulatedFRF(Result):
    """A predicted tool-point receptance ``h = u/F`` (what ``bayes-rcsa simulate`` writes).

    Attributes
    ----------
    frequency_hz : (n_freq,) Hz
    h : (n_freq,) complex, m/N
    setup_name : str, the setup's name (recorded in the file's first comment)
    tool : str
    direction : {"x", "y"}
    clamping_length : float, m
    kx : float, N/m, translational contact stiffness k_xf
    ktheta : float, N m/rad, rotational contact stiffness k_thetaM
    cx : float, N s/m, translational contact damping c_xf
    ctheta : float, N m s/rad, rotational contact damping c_thetaM
    path : path-like or None, the file it was saved to (as the caller named it) or loaded from
    warnings : tuple of str

    The contact values of a result loaded from a universal file whose ID line
    was cut at 80 characters may be ``None``.
    """

    title: ClassVar[str] = "Simulated tool-point FRF"
    files: ClassVar[tuple[str, ...]] = ()  # one file, named by the caller (.csv, .uff, .unv)

    frequency_hz: np.ndarray
    h: np.ndarray
    setup_name: str
    tool: str | None
    direction: str | None
    clamping_length: float | None
    kx: float | None
    ktheta: float | None
    cx: float | None = 0.0
    ctheta: float | None = 0.0
    path: Path | str | None = None
    warnings: tuple[str, ...] = field(default_factory=tuple)

    # -- numbers ---------------------------------------------------------------------------------------------
    @property
    def peak_index(self) -> int:
        """Line of the largest |h|."""
        return int(np.abs(self.h).argmax())

    @property
    def peak_hz(self) -> float:
        """Frequency of the largest |h|, Hz."""
        return float(self.frequency_hz[self.peak_index])

    @property
    def peak_abs_m_per_n(self) -> float:
        """The largest |h|, m/N."""
        return float(abs(self.h[self.peak_index]))

    def comments(self) -> list[str]:
        """The provenance lines written at the top of the file."""
        return [
            f"bayes-rcsa simulate: {self.setup_name}",
            f"tool={self.tool} direction={self.direction} clamping_length={self.clamping_length!r} m",
            f"k_xf={self.kx!r} N/m k_thetaM={self.ktheta!r} N*m/rad c_xf={self.cx!r} N*s/m "
            f"c_thetaM={self.ctheta!r} N*m*s/rad",
        ]

    def to_dict(self) -> dict:
        """The FRF and its inputs (the command writes the FRF file only; this is its content as JSON)."""
        return {
            "setup": self.setup_name, "tool": self.tool, "direction": self.direction,
            "clamping_length_m": self.clamping_length, "k_xf_n_per_m": self.kx, "k_thetaM_nm_per_rad": self.ktheta,
            "c_xf_ns_per_m": self.cx, "c_thetaM_nms_per_rad": self.ctheta,
            "frequency_hz": self.frequency_hz.tolist(), "real": self.h.real.tolist(), "imag": self.h.imag.tolist(),
            "warnings": list(self.warnings),
        }

    def headline(self) -> list[tuple[str, str]]:
        rows = []
        if self.clamping_length is not None:
            rows.append(("clamping length", length_mm(self.clamping_length)))
        if self.kx is not None:
            rows.append((parameter_name("k_xf"), sci(self.kx, 3, unit="N/m")))
        if self.ktheta is not None:
            rows.append((parameter_name("k_thetaM"), sci(self.ktheta, 3, unit="N m/rad")))
        return rows + [
            ("frequency range", f"{self.frequency_hz[0]:g}–{self.frequency_hz[-1]:g} Hz ({self.frequency_hz.size} lines)"),
            ("largest |h|", f"{sci(self.peak_abs_m_per_n, 3, unit='m/N')} at {hz(self.peak_hz)}"),
        ]

    def summary_line(self) -> str:
        f = self.frequency_hz
        return (f"wrote {self.path} ({f.size} lines, {f[0]:g}–{f[-1]:g} Hz; largest |h| "
                f"{sci(self.peak_abs_m_per_n, 3, unit='m/N')} at {hz(self.peak_hz)})")

    def summary_data(self) -> dict:
        return {"n_lines": int(self.frequency_hz.size), "peak_hz": self.peak_hz,
                "peak_abs_m_per_n": self.peak_abs_m_per_n}

    # -- files -----------------------------------------------------------------------------------------------
    @staticmethod
    def check_output(path, force: bool = False) -> Path:
        """Refuse an output file of an unknown type, or an existing one without ``force`` (before any work).

        Raises
        ------
        SetupError
            ``"--out FILE: unsupported FRF output type ..."`` or ``"--out FILE: exists; use --force to replace it"``.
        """
        from ..io.writers import frf_writer_for

        frf_writer_for(path)
        if Path(path).exists() and not force:
            raise SetupError(f"--out {path}: exists; use --force to replace it")
        return Path(path)

    def save(self, folder, *, force: bool = False, plots: bool = True) -> Path:
        """Write the FRF file ``folder`` (a file name: ``.csv``, or ``.uff``/``.unv`` for dataset 58), atomically.

        ``plots`` is accepted for a uniform interface; the command writes no plot.
        """
        from ..io.writers import write_frf
        from ..model import FRF

        path = self.check_output(folder, force)
        write_frf(path, FRF(self.frequency_hz, self.h, source=str(folder)), comments=self.comments())
        self.path = folder  # as named by the caller: the closing line repeats it
        return path

    @classmethod
    def load(cls, folder) -> "SimulatedFRF":
        """Read an FRF file written by :meth:`save` (or ``bayes-rcsa simulate``)."""
        from ..io import read_frf

        path = Path(folder)
        frf = read_frf(path)
        text = path.read_text(encoding="utf-8", errors="replace")
        if path.suffix.lower() == ".csv":
            text = "\n".join(ln[1:] for ln in text.splitlines() if ln.startswith("#"))
        found = {k: v for k, v in re.findall(r"\b(tool|direction|clamping_length|k_xf|k_thetaM|c_xf|c_thetaM)=(\S+)",
                                            text)}
        name = re.search(r"bayes-rcsa simulate: (.*?)(?:;|\n|$)", text)
        if name is None:
            raise DataError(f"{path}: no 'bayes-rcsa simulate' provenance line; not written by simulate")

        def number(key):
            try:
                value = float(found[key])
            except (KeyError, ValueError):
                return None
            return value if math.isfinite(value) else None

        return cls(frequency_hz=np.asarray(frf.frequency_hz, dtype=float), h=np.asarray(frf.values),
                   setup_name=name.group(1).strip(), tool=found.get("tool"), direction=found.get("direction"),
                   clamping_length=number("clamping_length"), kx=number("k_xf"), ktheta=number("k_thetaM"),
                   cx=number("c_xf"), ctheta=number("c_thetaM"), path=path)

    # -- pictures --------------------------------------------------------------------------------------------
    def figures(self) -> dict:
        """``{"frf": Figure}``: |h| (m/N, log scale) and phase (deg) over frequency (Hz)."""
        from ..io.figures import finish, new_figure

        fig = new_figure(7, 5)
        am, ap = fig.subplots(2, 1, sharex=True)
        am.semilogy(self.frequency_hz, np.abs(self.h), color="tab:blue", lw=1.2)
        am.set_ylabel("|h| (m/N)")
        ap.plot(self.frequency_hz, np.degrees(np.angle(self.h)), color="tab:blue", lw=1.2)
        ap.set_ylabel("phase (deg)")
        ap.set_xlabel("frequency (Hz)")
        length = "" if self.clamping_length is None else f", clamping length {self.clamping_length * 1e3:g} mm"
        fig.suptitle(f"simulated tool-point FRF, direction {self.direction}{length}", fontsize=10)
        finish(fig)
        return {"frf": fig}


def _positive(value, name: str) -> float:
    v = float(value)
    if not math.isfinite(v) or v <= 0:
        raise SetupError(f"{name} {value!r}: expected a finite number > 0")
    return v


def simulate(setup, *, clamping_length: float, kx: float, ktheta: float, cx: float = 0.0, ctheta: float = 0.0,
             direction: str = "x", tool: str | None = None, frequency_hz=None) -> SimulatedFRF:
    """Predict the tool-point receptance of ``setup`` at one clamping length for given contact parameters.

    Parameters
    ----------
    setup : path of the setup TOML file, or a loaded :class:`bayes_rcsa.io.setup.Setup` (with its spindle files)
    clamping_length : float, m
    kx : float, N/m, translational contact stiffness k_xf (> 0)
    ktheta : float, N m/rad, rotational contact stiffness k_thetaM (> 0)
    cx : float, N s/m, translational contact damping c_xf (>= 0)
    ctheta : float, N m s/rad, rotational contact damping c_thetaM (>= 0)
    direction : {"x", "y"}, spindle direction
    tool : str, optional; default the setup's only tool
    frequency_hz : (n_freq,) Hz, optional; default the spindle file's grid

    Returns
    -------
    SimulatedFRF

    Raises
    ------
    SetupError
        Negative damping, several tools and none named, an unreadable setup.
    """
    with warning_log() as log:
        clamping_length = _positive(clamping_length, "clamping_length")
        kx, ktheta = _positive(kx, "kx"), _positive(ktheta, "ktheta")
        cx, ctheta = float(cx), float(ctheta)
        if cx < 0 or ctheta < 0:
            raise SetupError("--cx/--ctheta: expected damping >= 0")
        if direction not in ("x", "y"):
            raise SetupError(f"direction {direction!r}: expected 'x' or 'y'")
        from ..io.setup import Setup, load_setup
        from ..model import Configuration

        if not isinstance(setup, Setup):
            setup = load_setup(setup, load_data=False, load_spindle=True)
        if tool is None:
            if len(setup.tools) != 1:
                raise SetupError(f"--tool: the setup defines several tools {sorted(setup.tools)}; name one")
            tool = next(iter(setup.tools))
        model = setup.model()
        freq = (model.spindle_receptance(direction).frequency_hz if frequency_hz is None
                else np.asarray(frequency_hz, dtype=float))
        h = model.frf(Configuration(clamping_length, direction, tool), freq, kx, ktheta, cx, ctheta)
    return SimulatedFRF(frequency_hz=freq, h=np.asarray(h), setup_name=setup.name, tool=tool, direction=direction,
                        clamping_length=clamping_length, kx=kx, ktheta=ktheta, cx=cx, ctheta=ctheta,
                        warnings=tuple(log))
