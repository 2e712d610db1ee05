"""Files of a fitted library: population.nc, the law table, the shrinkage plot, library.json.

``population.nc`` (ArviZ InferenceData, readable by ``arviz.from_netcdf``):
group ``posterior`` holds ``a``, ``b``, ``sigma`` with dims ``(chain, draw,
holder_type, coordinate)`` (one chain of evenly thinned draws per type);
``constant_data`` the per-setup summary.  Attributes: ``model_version``,
``pooled_parameters`` (the coordinates' names; xarray reserves
``coordinates``), ``coordinate_units``, ``scales``, ``holder_types``,
``covariate`` (its definition), ``d_ref_m``, ``l_a``, ``l_b``,
``growth_bound``, ``box`` and ``diameters`` (JSON), ``hyperprior`` (JSON).
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np

from ..errors import DataError
from .population import D_REF, MODEL_VERSION, SCALES, coordinate_units
from .predictive import Population

__all__ = ["write_population", "read_population", "law_table", "write_law_table", "shrinkage_plot", "shrinkage_figure",
           "MAX_DRAWS"]

#: Hyperparameter draws stored per holder type (evenly thinned).
MAX_DRAWS = 4000


def _thin(draws: np.ndarray, n: int) -> np.ndarray:
    idx = np.linspace(0, draws.shape[0] - 1, n).round().astype(int)
    return draws[idx]


def write_population(path, pop: Population, setups: list[dict], hyper_description: dict, attrs: dict | None = None):
    """Write ``population.nc`` atomically.

    Parameters
    ----------
    path : path-like
    pop : Population
    setups : list of dict, per-setup rows (name, holder_type, diameter_m, ess, p_value, p_adequacy, outlier,
        own/pooled medians)
    hyper_description : dict, :meth:`Hyperprior.describe`
    attrs : dict, extra attributes (warnings, seed)
    """
    from ..inference.diagnostics import inference_data_from_dict
    from ..store import write_netcdf

    types = pop.holder_types
    d = len(pop.names)
    n = min(MAX_DRAWS, min(pop.draws[t].shape[0] for t in types))
    stack = np.stack([_thin(pop.draws[t], n) for t in types], axis=1)  # (n, T, 3d)
    post = {"a": stack[None, :, :, :d], "b": stack[None, :, :, d:2 * d], "sigma": stack[None, :, :, 2 * d:]}
    const = {
        "setup_holder_type": np.array([s["holder_type"] for s in setups]),
        "setup_diameter_m": np.array([s["diameter_m"] for s in setups], dtype=float),
        "setup_ess": np.array([s["ess"] for s in setups], dtype=float),
        "setup_p_value": np.array([np.nan if s.get("p_value") is None else s["p_value"] for s in setups], dtype=float),
        # the model-adequacy component of the outlier check (NaN: skipped, e.g. no stage-1 summary)
        "setup_p_adequacy": np.array([np.nan if s.get("p_adequacy") is None else s["p_adequacy"] for s in setups],
                                     dtype=float),
        "setup_outlier": np.array([int(bool(s.get("outlier"))) for s in setups]),
        "setup_own_median": np.array([[s[f"{c}_own"][1] for c in pop.names] for s in setups], dtype=float),
        "setup_pooled_median": np.array([[s[f"{c}_pooled"][1] if f"{c}_pooled" in s else np.nan for c in pop.names]
                                         for s in setups], dtype=float),
    }
    dims = {v: ["holder_type", "coordinate"] for v in post}
    dims.update({k: ["setup"] for k in const if k not in ("setup_own_median", "setup_pooled_median")})
    dims.update({"setup_own_median": ["setup", "coordinate"], "setup_pooled_median": ["setup", "coordinate"]})
    a = {
        "model_version": MODEL_VERSION, "created_by": "bayes_rcsa library",
        "pooled_parameters": json.dumps(list(pop.names)),
        "coordinate_units": json.dumps({c: coordinate_units(c) for c in pop.names}),
        "scales": json.dumps({c: SCALES[c] for c in pop.names}),
        "holder_types": json.dumps(list(types)),
        "covariate": "x = ln(d / d_ref), d the tool's shank diameter in m, d_ref = d_ref_m",
        "d_ref_m": D_REF, "l_a": pop.growth[0], "l_b": pop.growth[1], "growth_bound": pop.growth[2],
        "box": json.dumps(pop.box.tolist()),
        "diameters": json.dumps({t: list(v) for t, v in pop.diameters.items()}),
        "hyperprior": json.dumps(hyper_description),
        **(attrs or {}),
    }
    coords = {"holder_type": list(types), "coordinate": list(pop.names), "setup": [s["name"] for s in setups]}
    idata = inference_data_from_dict(posterior=post, constant_data=const, dims=dims, coords=coords, attrs=a)
    return write_netcdf(idata, path)


def read_population(path) -> Population:
    """Read ``population.nc``.

    Raises
    ------
    DataError
        Missing or unreadable file, or a file of another model version (refit the library).
    """
    from ..store import read_netcdf

    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: population file not found (expected DIR/population.nc written by 'bayes-rcsa "
                        "library')")
    try:
        idata = read_netcdf(path)
        post = idata.posterior
    except Exception as exc:  # netCDF/HDF5 readers raise many unrelated types
        raise DataError(f"{path}: cannot read as a population file ({type(exc).__name__}: {exc})") from None
    attrs = {}
    for group in (idata, getattr(idata, "constant_data", None), post):  # ArviZ puts them on the root group
        attrs.update(dict(getattr(group, "attrs", None) or {}))
    version = attrs.get("model_version")
    if version != MODEL_VERSION:
        raise DataError(f"{path}: model_version {version!r}, expected {MODEL_VERSION!r}; the population was fitted "
                        "by another version of the model: rerun 'bayes-rcsa library'")
    try:
        names = tuple(json.loads(attrs["pooled_parameters"]))
        types = tuple(json.loads(attrs["holder_types"]))
        draws = {}
        for i, t in enumerate(types):
            parts = [np.asarray(post[v].values)[:, :, i, :].reshape(-1, len(names)) for v in ("a", "b", "sigma")]
            draws[t] = np.concatenate(parts, axis=1)
        box = np.asarray(json.loads(attrs["box"]), dtype=float)
        diam = {t: tuple(v) for t, v in json.loads(attrs["diameters"]).items()}
        growth = (float(attrs["l_a"]), float(attrs["l_b"]), float(attrs["growth_bound"]))
        const = getattr(idata, "constant_data", None)
        setup_types = [str(v) for v in np.asarray(const["setup_holder_type"].values).ravel()] \
            if const is not None and "setup_holder_type" in const else []
        counts = {t: setup_types.count(t) for t in types} if setup_types else {}
    except (KeyError, ValueError, TypeError, IndexError) as exc:
        raise DataError(f"{path}: malformed population file ({type(exc).__name__}: {exc})") from None
    if box.shape != (len(names), 2) or not all(np.all(np.isfinite(v)) for v in draws.values()):
        raise DataError(f"{path}: malformed population file (box {box.shape}, {len(names)} coordinates)")
    return Population(names, draws, box, growth, diam, str(version), counts)


def law_table(pop: Population) -> list[dict]:
    """Per holder type and parameter: the population median at 10 mm (physical), slope and spread, 90 % intervals.

    Returns
    -------
    list of dict with ``holder_type``, ``parameter``, ``unit`` (of the physical value), ``coordinate_unit``,
    ``median_at_10mm`` and its ``q05``/``q95`` (physical units), ``slope_q05/q50/q95`` (coordinate units
    per unit of ln d), ``spread_q05/q50/q95`` (coordinate units)
    """
    rows = []
    d = len(pop.names)
    for t in pop.holder_types:
        th = pop.draws[t]
        for j, n in enumerate(pop.names):
            qa = np.quantile(th[:, j], [0.05, 0.5, 0.95])
            qb = np.quantile(th[:, d + j], [0.05, 0.5, 0.95])
            qs = np.quantile(th[:, 2 * d + j], [0.05, 0.5, 0.95])
            phys = 10.0 ** qa if SCALES[n] == "log10" else qa
            unit = coordinate_units(n)
            rows.append({
                "holder_type": t, "parameter": n, "unit": unit[6:-1] if unit.startswith("log10(") else unit,
                "coordinate_unit": unit,
                "median_at_10mm_q05": float(phys[0]), "median_at_10mm": float(phys[1]),
                "median_at_10mm_q95": float(phys[2]),
                "slope_q05": float(qb[0]), "slope_q50": float(qb[1]), "slope_q95": float(qb[2]),
                "spread_q05": float(qs[0]), "spread_q50": float(qs[1]), "spread_q95": float(qs[2]),
            })
    return rows


def write_law_table(out_dir, rows: list[dict]) -> tuple[Path, Path]:
    """``laws.json`` and ``laws.csv`` in ``out_dir`` (atomic)."""
    from ..io.atomic import atomic_write_text

    out = Path(out_dir)
    atomic_write_text(out / "laws.json", json.dumps({"laws": rows}, indent=1))
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]) if rows else ["holder_type"])
    w.writeheader()
    w.writerows(rows)
    atomic_write_text(out / "laws.csv", buf.getvalue())
    return out / "laws.json", out / "laws.csv"


def shrinkage_plot(path, names, setups: list[dict]) -> Path:
    """:func:`shrinkage_figure` written to ``path`` (PNG)."""
    from ..io.figures import save_png

    return save_png(shrinkage_figure(names, setups), path)


def shrinkage_figure(names, setups: list[dict]):
    """Each setup's own stage-1 median and 90 % interval against its pooled one, per coordinate, vs diameter."""
    from ..io.figures import finish, new_figure

    fig = new_figure(4.0 * len(names), 3.6)
    types = sorted({s["holder_type"] for s in setups})
    colours = {t: f"C{i % 10}" for i, t in enumerate(types)}
    for j, n in enumerate(names):
        ax = fig.add_subplot(1, len(names), j + 1)
        for s in setups:
            dmm = s["diameter_m"] * 1e3
            own = s[f"{n}_own"]
            c = colours[s["holder_type"]]
            ax.errorbar([dmm - 0.15], [own[1]], yerr=[[own[1] - own[0]], [own[2] - own[1]]], fmt="o", mfc="none",
                        color=c, ms=4, lw=0.8)
            if f"{n}_pooled" in s:
                pooled = s[f"{n}_pooled"]
                ax.errorbar([dmm + 0.15], [pooled[1]], yerr=[[pooled[1] - pooled[0]], [pooled[2] - pooled[1]]],
                            fmt="o", color=c, ms=4, lw=1.2)
            if s.get("outlier"):
                ax.annotate(s["name"], (dmm, own[1]), textcoords="offset points", xytext=(5, 3), color="red")
        ax.set_xlabel("shank diameter (mm)")
        ax.set_ylabel(f"{n} [{coordinate_units(n)}]")
    handles = [fig.axes[0].plot([], [], "o", color=colours[t], label=t)[0] for t in types]
    handles += [fig.axes[0].plot([], [], "o", mfc="none", color="k", label="own (stage 1)")[0],
                fig.axes[0].plot([], [], "o", color="k", label="pooled")[0]]
    fig.legend(handles=handles, loc="upper center", ncol=len(handles), fontsize=8, frameon=False)
    finish(fig, rect=(0, 0, 1, 0.9))
    return fig
