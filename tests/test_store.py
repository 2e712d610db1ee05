"""bayes_rcsa.store: the one owner of posterior.nc (schema version, writer, reader, append) and of netCDF I/O (#41)."""

from __future__ import annotations

import ast
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import bayes_rcsa.store as store
from bayes_rcsa.data import example_dir
from bayes_rcsa.errors import DataError, SetupError
from bayes_rcsa.store import posterior_file

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "bayes_rcsa"

N_CHAIN, N_DRAW, N_LINE = 3, 20, 4


def _pm():
    from bayes_rcsa.params import LogUniform, ParameterModel, Uniform
    from bayes_rcsa.params.growth import GrowthLaw

    return ParameterModel.from_priors(GrowthLaw(0.025, 0.040, 0.5),
                                      {"k_xf": LogUniform(1e5, 1e9), "k_thetaM": LogUniform(1e3, 1e8),
                                       "g_xf": Uniform(0, 0.5), "g_thetaM": Uniform(0, 0.5),
                                       "sigma_0": LogUniform(1e-4, 10)},
                                      {"c_xf": 10.0, "c_thetaM": 5e-4}, n_measurements=1)


def _idata(seed: int = 0):
    """A small posterior of the example setup's contact (draws around its truth), as identify lays it out."""
    from bayes_rcsa.inference.diagnostics import build_inference_data

    rng = np.random.default_rng(seed)
    pm = _pm()
    base = {"k_xf": 1.8e6, "k_thetaM": 4.5e5, "g_xf": 0.45, "g_thetaM": 0.45}
    post = {name: (base[name] * np.exp(rng.normal(0, 0.03, (N_CHAIN, N_DRAW))) if name.startswith("k_") else
                   np.full((N_CHAIN, N_DRAW), base.get(name, 0.01))) for name in pm.names}
    return build_inference_data(post, rng.normal(size=(N_CHAIN, N_DRAW)), rng.normal(size=(N_CHAIN, N_DRAW, N_LINE)),
                                np.ones(N_LINE, complex) * (1 + 2j),
                                {"fit_clamping_length": np.array([0.025, 0.03, 0.035, 0.04])},
                                {"fit_clamping_length": ["fm"]}, {"fm": list("abcd")},
                                {"method": "multi", "tempering": 0.5, "parameter_model": json.dumps(pm.to_dict())})


def _with_root_attrs(src, dst: Path, **attrs) -> Path:
    """A copy of ``src`` (a file, or its InferenceData as read) whose root attributes are replaced (a file another
    program or version wrote)."""
    idata = src if hasattr(src, "groups") else store.read_netcdf(src)
    groups = {g: getattr(idata, g) for g in idata.groups()}
    root = {k: v for k, v in idata.attrs.items() if k != store.SCHEMA_ATTRIBUTE}
    root.update({k: v for k, v in attrs.items() if v is not None})
    return store.write_netcdf(type(idata)(attrs=root, **groups), dst)


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    root = tmp_path_factory.mktemp("store")
    idata = _idata()
    return idata, store.write_posterior(idata, root / "posterior.nc")


@pytest.fixture(scope="module")
def forged(written, tmp_path_factory):
    """``forged(version)``: the written file with schema attribute ``version`` (``None``: none, a version-1 file),
    made once per version for the tests that only read it (a read and a rewrite cost ~0.4 s; the tests made nine
    such files of six versions)."""
    root = tmp_path_factory.mktemp("forged")
    source = store.read_netcdf(written[1])
    made = {}

    def get(version):
        key = (type(version).__name__, repr(version))  # 7 and np.int64(7), 2 and "2" and 2.0 are different files
        if key not in made:
            made[key] = _with_root_attrs(source, root / f"v{len(made)}.nc", **{store.SCHEMA_ATTRIBUTE: version})
        return made[key]

    return get


# -- the public names ---------------------------------------------------------------------------------------------


def test_the_public_names():
    assert sorted(store.__all__) == sorted(["SCHEMA_VERSION", "SCHEMA_ATTRIBUTE", "write_posterior", "read_posterior",
                                            "append_to_posterior", "write_netcdf", "read_netcdf",
                                            "posterior_attributes"])
    assert store.SCHEMA_VERSION == 2 and isinstance(store.SCHEMA_VERSION, int)
    assert store.SCHEMA_ATTRIBUTE == "bayes_rcsa_schema_version"


# -- write and read -----------------------------------------------------------------------------------------------


def test_write_read_round_trip_keeps_values_groups_attributes_and_records_the_schema(written):
    import h5py

    idata, path = written
    assert store.SCHEMA_ATTRIBUTE not in idata.attrs  # the caller's object is not modified
    back = store.read_posterior(path)
    assert back.groups() == idata.groups()
    for group in idata.groups():
        a, b = getattr(idata, group), getattr(back, group)
        assert set(a.data_vars) == set(b.data_vars), group
        for name in a.data_vars:
            # float64 everywhere, except the pointwise log-likelihood (float32 on disk)
            rtol = 1e-7 if group == "log_likelihood" else 0.0
            np.testing.assert_allclose(b[name].values, a[name].values, rtol=rtol, err_msg=f"{group}/{name}")
    assert back.attrs[store.SCHEMA_ATTRIBUTE] == store.SCHEMA_VERSION
    assert back.attrs["method"] == "multi"
    attrs = store.posterior_attributes(back)
    assert attrs["method"] == "multi" and attrs["tempering"] == 0.5 and "parameter_model" in attrs
    assert store.SCHEMA_ATTRIBUTE not in attrs  # a file-level attribute, not one of the fit's
    with h5py.File(path, "r") as f:  # the compression of every posterior.nc (issue #14)
        assert f.attrs[store.SCHEMA_ATTRIBUTE] == 2
        for p in ("posterior/k_xf", "sample_stats/lp", "log_likelihood/frf", "constant_data/fit_clamping_length"):
            assert f[p].compression == "gzip" and f[p].shuffle, p
        assert f["log_likelihood/frf"].dtype == np.float32 and f["posterior/k_xf"].dtype == np.float64
    # the draws as every product reads them
    from bayes_rcsa.posterior import load_posterior

    d = load_posterior(path)
    np.testing.assert_array_equal(d.values["k_xf"], idata.posterior["k_xf"].values.ravel())
    assert d.fit_lengths == (0.025, 0.03, 0.035, 0.04)


def test_the_array_reader_gives_the_values_and_attributes_arviz_reads(written):
    """``read_posterior(..., arrays=True)`` (h5py only: what posterior-mode lobes and predict use to skip the ArviZ
    import) returns every group's variables, coordinates and attributes exactly as ``arviz.from_netcdf`` does."""
    idata, path = written
    full, light = store.read_posterior(path), store.read_posterior(path, arrays=True)
    assert light.groups() == full.groups()
    assert dict(light.attrs) == {k: v for k, v in full.attrs.items()}
    for group in full.groups():
        a, b = getattr(full, group), getattr(light, group)
        assert set(b.data_vars) == set(a.data_vars), group
        assert set(b.coords) == set(a.coords), group
        assert b.attrs == dict(a.attrs), group
        for name in [*a.data_vars, *a.coords]:
            assert b[name].values.dtype == a[name].values.dtype, (group, name)
            np.testing.assert_array_equal(b[name].values, a[name].values, err_msg=f"{group}/{name}")
    assert light.no_such_group is None
    assert store.posterior_attributes(light) == store.posterior_attributes(full)
    from bayes_rcsa.posterior import load_posterior

    a, b = load_posterior(path), load_posterior(path, inference_data=light)
    assert a.fit_lengths == b.fit_lengths and a.method == b.method and a.parameters.to_dict() == b.parameters.to_dict()
    for name in a.values:
        np.testing.assert_array_equal(a.values[name], b.values[name])


def test_the_array_reader_refuses_a_newer_schema_in_the_same_line(forged):
    bad = forged(np.int64(7))
    with pytest.raises(DataError, match="schema version 7 is newer than this bayes_rcsa reads"):
        store.read_posterior(bad, option=None, arrays=True)


def test_a_version_1_file_without_the_attribute_is_read_as_before(written, forged):
    from bayes_rcsa.posterior import load_posterior

    idata, path = written
    old = forged(None)
    assert store.SCHEMA_ATTRIBUTE not in store.read_netcdf(old).attrs
    back = store.read_posterior(old)
    assert posterior_file._schema_version(back, old) == 1
    np.testing.assert_array_equal(back.posterior["k_thetaM"].values, idata.posterior["k_thetaM"].values)
    np.testing.assert_array_equal(load_posterior(old).values["k_xf"], load_posterior(path).values["k_xf"])


@pytest.mark.parametrize("version, needle", [
    (3, "posterior.nc schema version 3 is newer than this bayes_rcsa reads (2); update bayes_rcsa"),
    (np.int64(7), "posterior.nc schema version 7 is newer than this bayes_rcsa reads (2)"),
    ("2", "posterior.nc schema version '2' is not an integer"),
    (2.0, "posterior.nc schema version 2.0 is not an integer"),
    (0, "posterior.nc schema version 0 is not a version of bayes_rcsa's"),
])
def test_a_newer_or_malformed_schema_version_is_refused_in_one_line(forged, version, needle):
    from bayes_rcsa.posterior import load_posterior
    from bayes_rcsa.stability.coefficients import read_coefficient_draws

    bad = forged(version)
    for read in (store.read_posterior, load_posterior, read_coefficient_draws):
        with pytest.raises(DataError) as info:
            read(bad)
        msg = str(info.value)
        assert msg.startswith(f"{bad}: ") and needle in msg and "\n" not in msg, (read, msg)


def test_the_readers_messages_are_kept(tmp_path):
    missing = tmp_path / "none" / "posterior.nc"
    with pytest.raises(SetupError) as info:
        store.read_posterior(missing)
    assert str(info.value) == f"--posterior {missing}: no such file (posterior.nc written by 'bayes-rcsa identify')"
    with pytest.raises(SetupError, match=r"^--model-posterior "):
        store.read_posterior(missing, option="--model-posterior")
    with pytest.raises(DataError) as info:
        store.read_posterior(missing, option=None)
    assert str(info.value) == (f"{missing}: posterior file not found (expected DIR/posterior.nc written by "
                               "'bayes-rcsa identify')")
    junk = tmp_path / "junk.nc"
    junk.write_text("not netCDF\n")
    with pytest.raises(DataError, match=r"cannot read as an ArviZ InferenceData netCDF file \("):
        store.read_posterior(junk)
    # an InferenceData without a posterior group (a population file, say) is not a posterior
    from bayes_rcsa.inference.diagnostics import inference_data_from_dict

    other = store.write_netcdf(inference_data_from_dict(constant_data={"x": np.zeros(2)}), tmp_path / "other.nc")
    with pytest.raises(DataError) as info:
        store.read_posterior(other)
    assert str(info.value) == f"{other}: no 'posterior' group"


# -- append -------------------------------------------------------------------------------------------------------


def test_append_to_posterior_adds_variables_groups_attributes_and_keeps_the_rest(written, forged, tmp_path):
    import xarray as xr

    from bayes_rcsa.posterior import load_posterior

    idata, src = written
    path = Path(shutil.copy(forged(None), tmp_path / "posterior.nc"))  # appending to a version-1 file upgrades it
    before = store.read_posterior(path)
    n = N_CHAIN * N_DRAW
    flat = np.arange(n, dtype=float) + 1.0  # the chain-flattened order of load_posterior
    square = np.arange(n, dtype=float).reshape(N_CHAIN, N_DRAW) * 2
    extra = xr.Dataset({"note_values": ("k", np.array([1.0, 2.0]))})
    assert store.append_to_posterior(path, posterior_vars={"flat_var": flat, "square_var": square},
                                     groups={"extra_group": extra},
                                     attrs={"n_cuts": 6, "cuts_file": "c.csv", "flag": True, "info": {"a": 1}}) == path
    after = store.read_posterior(path)
    assert after.attrs[store.SCHEMA_ATTRIBUTE] == store.SCHEMA_VERSION
    assert after.attrs["method"] == "multi"  # root attributes kept
    np.testing.assert_array_equal(load_posterior(path).values["k_xf"], load_posterior(src).values["k_xf"])
    np.testing.assert_array_equal(after.posterior["flat_var"].values.ravel(), flat)
    np.testing.assert_array_equal(after.posterior["square_var"].values, square)
    assert after.posterior["flat_var"].dims == ("chain", "draw")
    np.testing.assert_array_equal(after.extra_group["note_values"].values, [1.0, 2.0])
    assert set(after.groups()) == set(before.groups()) | {"extra_group"}
    for group in before.groups():
        for name in getattr(before, group).data_vars:
            np.testing.assert_array_equal(getattr(after, group)[name].values, getattr(before, group)[name].values)
    attrs = store.posterior_attributes(after)
    assert attrs["n_cuts"] == 6 and attrs["cuts_file"] == "c.csv" and attrs["flag"] == 1
    assert json.loads(attrs["info"]) == {"a": 1} and attrs["parameter_model"] == store.posterior_attributes(before)[
        "parameter_model"]
    with pytest.raises(DataError, match=r"wrong has shape \(7,\); expected 60 draws"):
        store.append_to_posterior(path, posterior_vars={"wrong": np.zeros(7)})
    assert "wrong" not in store.read_posterior(path).posterior  # nothing written on a refusal


def test_add_coefficients_to_posterior_writes_through_the_store(written, tmp_path):
    from bayes_rcsa.cuts.joint import add_coefficients_to_posterior
    from bayes_rcsa.stability.coefficients import read_coefficient_draws

    path = Path(shutil.copy(written[1], tmp_path / "posterior.nc"))
    n = N_CHAIN * N_DRAW
    kt, kr, w = np.linspace(5e8, 7e8, n), np.linspace(1e8, 2e8, n), np.full(n, 0.1)
    add_coefficients_to_posterior(path, kt, kr, w, {"cuts_file": "cuts.csv", "n_cuts": 4})
    got = read_coefficient_draws(path)
    np.testing.assert_array_equal(got[0], kt)
    np.testing.assert_array_equal(got[1], kr)
    assert store.posterior_attributes(store.read_posterior(path))["n_cuts"] == 4


def test_every_posterior_read_goes_through_the_one_opener(written, monkeypatch):
    from bayes_rcsa.design.workflow import posterior_attributes as design_attributes
    from bayes_rcsa.posterior import load_posterior
    from bayes_rcsa.stability.coefficients import read_coefficient_draws

    path = written[1]
    opened = []
    real = posterior_file._open_posterior
    monkeypatch.setattr(posterior_file, "_open_posterior", lambda p, *a: opened.append(Path(p)) or real(p, *a))
    for read in (store.read_posterior, load_posterior, read_coefficient_draws, design_attributes):
        del opened[:]
        read(path)
        assert opened == [path], read


# -- through the command line -------------------------------------------------------------------------------------


def _predict(setup, posterior, out):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "bayes_rcsa", "predict", str(setup), "--posterior", str(posterior),
                           "--lengths", "0.03", "--max-draws", "10", "--no-plots", "--quiet", "--out", str(out)],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)


def test_predict_refuses_a_newer_posterior_in_one_line_exit_2(forged, tmp_path):
    shutil.copytree(example_dir(), tmp_path / "data")
    newer = forged(3)
    res = _predict(tmp_path / "data" / "setup.toml", newer, tmp_path / "out")
    assert res.returncode == 2, res.stderr[-2000:]
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, res.stderr
    assert str(newer) in lines[0] and "schema version 3 is newer than this bayes_rcsa reads (2)" in lines[0]
    assert not (tmp_path / "out").exists()


def test_predict_reads_the_posterior_through_the_store(written, tmp_path, monkeypatch):
    from bayes_rcsa.cli.main import main

    shutil.copytree(example_dir(), tmp_path / "data")
    path = Path(shutil.copy(written[1], tmp_path / "posterior.nc"))
    opened = []
    real = posterior_file._open_posterior
    monkeypatch.setattr(posterior_file, "_open_posterior", lambda p, *a: opened.append(Path(p)) or real(p, *a))
    assert main(["predict", str(tmp_path / "data" / "setup.toml"), "--posterior", str(path), "--lengths", "0.03",
                 "--max-draws", "10", "--no-plots", "--quiet", "--out", str(tmp_path / "out")]) == 0
    assert opened and set(opened) == {path}
    assert (tmp_path / "out" / "frequencies.json").is_file()


# -- nobody else opens a netCDF file ------------------------------------------------------------------------------

#: Readers and writers of netCDF files (xarray, ArviZ); only bayes_rcsa/store/ may call them.
NETCDF_CALLS = {"to_netcdf", "from_netcdf", "open_dataset", "open_datatree", "load_dataset", "load_datatree",
                "open_mfdataset", "open_groups", "netcdf_file"}
#: Modules that read or write netCDF themselves.
NETCDF_MODULES = {"h5netcdf", "netCDF4", "scipy.io.netcdf", "netcdf"}
#: Calls that open a file given its name (builtins, pathlib, h5py, netCDF4).
OPENERS = {"open", "File", "Dataset", "read_bytes", "read_text", "write_bytes", "write_text", "fdopen"}
#: The store's own readers and writers; outside the store a posterior.nc goes to write_/read_posterior.
STORE_GENERIC = {"read_netcdf", "write_netcdf"}


def _call_name(func) -> str:
    return func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")


def _strings(node):
    return [n.value for n in ast.walk(node) if isinstance(n, ast.Constant) and isinstance(n.value, str)]


def netcdf_violations(source: str, where: str = "<source>") -> list[str]:
    """Every place in ``source`` that reads or writes a netCDF file without the store (one line each)."""
    out = []
    for node in ast.walk(ast.parse(source, where)):
        if isinstance(node, ast.Import):
            out += [f"{where}:{node.lineno}: import {a.name}" for a in node.names if a.name in NETCDF_MODULES
                    or a.name.split(".")[0] in {"h5netcdf", "netCDF4"}]
        elif isinstance(node, ast.ImportFrom):
            mod = node.module or ""
            if mod in NETCDF_MODULES or mod.split(".")[0] in {"h5netcdf", "netCDF4"}:
                out.append(f"{where}:{node.lineno}: from {mod} import ...")
            out += [f"{where}:{node.lineno}: import of {a.name}" for a in node.names if a.name in NETCDF_CALLS]
        elif isinstance(node, ast.Attribute) and node.attr in NETCDF_CALLS:
            out.append(f"{where}:{node.lineno}: .{node.attr}")
        elif isinstance(node, ast.Name) and node.id in NETCDF_CALLS:
            out.append(f"{where}:{node.lineno}: {node.id}")
        elif isinstance(node, ast.keyword) and node.arg == "engine" and isinstance(node.value, ast.Constant) \
                and str(node.value.value).lower() in {"h5netcdf", "netcdf4", "scipy"}:
            out.append(f"{where}:{node.lineno}: engine={node.value.value!r}")
        elif isinstance(node, ast.Call):
            name = _call_name(node.func)
            # the file of ``open(p)``, ``h5py.File(p)`` is an argument, of ``p.read_bytes()`` the receiver; only
            # these calls' strings matter (walking every call's, and formatting a location per node rather than per
            # hit, cost ~0.7 s of the package scan's ~3.3 s)
            if name not in OPENERS and name not in STORE_GENERIC:
                continue
            args = [*node.args, *(k.value for k in node.keywords)]
            if isinstance(node.func, ast.Attribute):
                args.append(node.func.value)
            strings = [s for a in args for s in _strings(a)]
            if name in OPENERS and any(s.endswith(".nc") for s in strings):
                out.append(f"{where}:{node.lineno}: {name}() of a .nc file")
            if name in STORE_GENERIC and any(s.endswith("posterior.nc") for s in strings):
                out.append(f"{where}:{node.lineno}: {name}() of posterior.nc (use write_posterior/read_posterior)")
    return out


@pytest.mark.parametrize("code", [
    "import arviz as az\naz.from_netcdf(path)",
    "idata.to_netcdf(path)",
    "import xarray as xr\nxr.open_dataset(p, group='posterior')",
    "from xarray import open_datatree",
    "import h5netcdf",
    "from h5netcdf import File",
    "import netCDF4",
    "ds.to_zarr(p, engine='h5netcdf')",
    "import h5py\nh5py.File(out / 'posterior.nc', 'r')",
    "with open(folder / 'population.nc', 'rb') as f: pass",
    "(out / 'posterior.nc').read_bytes()",
    "from bayes_rcsa.store import read_netcdf\nread_netcdf(folder / 'posterior.nc')",
])
def test_the_netcdf_scan_finds_a_reader_outside_the_store(code):
    assert netcdf_violations(code), code


@pytest.mark.parametrize("code", [
    # inference/checkpoint.py: chain.h5 (h5py), not a netCDF file
    "import h5py\nwith h5py.File(tmp, 'w', locking=False) as f: f.create_dataset('chain', data=x)",
    '"""Readable by ``arviz.from_netcdf``; h5netcdf writes it."""',
    "(out / 'posterior.nc').is_file()",
    "store.read_posterior(out / 'posterior.nc')",
    "store.read_netcdf(folder / 'population.nc')",
    "pd.read_csv(p, engine='python')",
])
def test_the_netcdf_scan_leaves_other_code_alone(code):
    assert netcdf_violations(code) == [], code


def test_only_the_store_reads_or_writes_netcdf_files():
    found = []
    for f in sorted(PACKAGE.rglob("*.py")):
        rel = f.relative_to(ROOT)
        if rel.parts[:2] == ("bayes_rcsa", "store"):
            continue
        found += netcdf_violations(f.read_text(), str(rel))
    assert not found, "\n".join(found)


def test_groups_built_without_arviz_are_arviz_from_dict_s():
    # build_inference_data lays the groups out itself (ArviZ's import costs seconds of identify's start-up); the
    # written file must stay what arviz.from_dict + to_netcdf made: the same groups, variables (in the same order),
    # dims, coordinates and attributes, with unnamed dims named <var>_dim_<i>
    import warnings

    import arviz
    import xarray as xr

    from bayes_rcsa.inference.diagnostics import _attr, build_inference_data

    rng = np.random.default_rng(3)
    post = {"k_xf": rng.normal(size=(3, 5)), "k_xf_at_length": rng.normal(size=(3, 5, 2)),
            "unnamed": rng.normal(size=(3, 5, 4))}
    args = (post, rng.normal(size=(3, 5)), rng.normal(size=(3, 5, 6)), rng.normal(size=6) + 1j,
            {"frequency_hz": np.arange(6.0), "fit_clamping_length": np.array([0.025, 0.04])},
            {"k_xf_at_length": ["clamping_length"], "frequency_hz": ["line"], "fit_clamping_length": ["fm"]},
            {"clamping_length": [0.025, 0.04], "fm": ["a", "b"], "line": np.arange(6)},
            {"method": "multi", "converged": True, "tempering": 0.5})
    ours = build_inference_data(*args)
    post_, lp, ll, obs, const, dims, coords, attrs = args
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        want = arviz.from_dict(posterior=post_, sample_stats={"lp": lp}, log_likelihood={"frf": ll},
                               observed_data={"frf_real": obs.real, "frf_imag": obs.imag}, constant_data=const,
                               dims={**dims, "frf": ["line"], "frf_real": ["line"], "frf_imag": ["line"]},
                               coords=coords, attrs={k: _attr(v) for k, v in attrs.items()})
    assert ours.groups() == want.groups() and dict(ours.attrs) == dict(want.attrs)
    for g in want.groups():
        a, b = getattr(ours, g), getattr(want, g)
        assert list(ours.contents[g].variables) == list(b.variables), g  # the order the file stores them in
        xr.testing.assert_identical(a.assign_attrs(created_at=""), b.assign_attrs(created_at=""))
    assert isinstance(ours.to_inference_data(), arviz.InferenceData)


def _xarray_written(groups, root_attrs, path) -> None:
    """The writer as it was (xarray's h5netcdf store with per-variable encodings): the reference for the direct one."""
    import h5netcdf
    import h5py
    import xarray as xr
    from xarray.backends import H5NetCDFStore

    def encoding(group, ds):
        out = {}
        for name, var in ds.variables.items():
            if var.dtype.kind in "fiub":
                out[name] = dict(store.netcdf.COMPRESSION)
                if group == "log_likelihood" and var.dtype.kind == "f" and name not in ds.coords:
                    out[name]["dtype"] = store.netcdf.LOG_LIKELIHOOD_DTYPE
        return out

    with h5py.File(str(path), "w", track_order=True) as h5, h5netcdf.File(h5, "w") as f:
        xr.Dataset(attrs=dict(root_attrs)).dump_to_store(H5NetCDFStore(f, mode="a"))
        for group, ds in groups.items():
            if group == "log_likelihood":
                ds = ds.assign_attrs(stored_dtype=store.netcdf.LOG_LIKELIHOOD_DTYPE)
            ds.dump_to_store(H5NetCDFStore(f, group=group, mode="a"), encoding=encoding(group, ds))


def _hdf5_objects(path, skip=()) -> list:
    """Every group, attribute and dataset of an HDF5 file with its type, dtype, shape, chunks, filters, fill value
    and bytes (dimension-scale references only as present/absent: they are object addresses)."""
    import h5py

    def attrs(node):
        return [(k, type(v).__name__, str(getattr(v, "dtype", "")), repr(v)) for k, v in node.attrs.items()
                if k not in ("DIMENSION_LIST", "REFERENCE_LIST", *skip)]

    out = []
    with h5py.File(path, "r") as f:
        out.append(attrs(f))
        for g in f:
            out.append((g, attrs(f[g])))
            for n, d in f[g].items():
                data = d[()]
                out.append((g, n, str(d.dtype), d.shape, d.chunks, d.compression, d.compression_opts, d.shuffle,
                            repr(d.fillvalue), attrs(d), "DIMENSION_LIST" in d.attrs, "REFERENCE_LIST" in d.attrs,
                            repr(data.tolist()) if data.dtype.kind in "OS" else data.tobytes()))
    return out


def test_the_direct_writer_writes_what_xarray_s_h5netcdf_store_wrote(tmp_path):
    # posterior.nc is written with h5netcdf directly (xarray, pandas and dask.array cost a second of identify's
    # start-up); object by object it must be the file xarray's store wrote: groups, attributes with their types,
    # variables in order with dtype, chunks, compression, fill value, dimension scales and bytes
    idata = _idata(4).to_inference_data()
    groups = {g: getattr(idata, g) for g in idata.groups()}
    root = {**idata.attrs, "flag": 1, "text": "x"}
    _xarray_written(groups, root, tmp_path / "reference.nc")
    store.netcdf._write_groups(groups, root, tmp_path / "direct.nc")
    store.netcdf._write_groups(_idata(4).contents, root, tmp_path / "contents.nc")
    want = _hdf5_objects(tmp_path / "reference.nc")
    assert _hdf5_objects(tmp_path / "direct.nc") == want
    # the same content built without xarray (identify's path): only the groups' creation times differ
    assert _hdf5_objects(tmp_path / "contents.nc", skip=("created_at",)) == \
        _hdf5_objects(tmp_path / "reference.nc", skip=("created_at",))
