"""Fast paths of the store and of the zero-order stability method give the numbers of their reference paths.

- :func:`bayes_rcsa.store.read_netcdf` reads the package's plain layout with h5py instead of
  ``arviz.from_netcdf``: the same groups, variables (in order), dims, coordinates, indexes, attributes (with their
  types), dtypes and bytes, on files of every writer the package has had; other files still go to ArviZ.
- :func:`bayes_rcsa.stability.zoa.oriented_eigenvalues` and ``_segment_ends`` work block by block of draws and
  on the parts of the eigenvalues: bit for bit the stacked eigenvalues of the whole array at once.
- :func:`bayes_rcsa.stability.simulate_milling` forms the cutter-angle factors and modal constants once and
  reuses each step's delayed motion at the next step's start: the numbers of the stage-by-stage version.
"""

from __future__ import annotations

import json
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import bayes_rcsa.store as store
from bayes_rcsa.store import netcdf

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_store import _idata  # noqa: E402  (the store tests' small posterior)


def _arviz():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        import arviz

    return arviz


def _assert_same_inference_data(a, b):
    """``a`` (arviz.from_netcdf) and ``b`` hold the same groups, variables, coordinates, attributes and bytes."""
    import xarray as xr

    def same_attrs(x, y, where):
        assert list(x) == list(y), where
        for k in x:
            assert type(x[k]) is type(y[k]), (where, k, type(x[k]), type(y[k]))
            assert np.array_equal(x[k], y[k]), (where, k)

    assert type(a) is type(b) and a.groups() == b.groups()
    same_attrs(a.attrs, b.attrs, "root")
    for g in a.groups():
        x, y = getattr(a, g), getattr(b, g)
        xr.testing.assert_identical(x, y)
        assert list(x.variables) == list(y.variables), g
        assert list(x.coords) == list(y.coords) and list(x.data_vars) == list(y.data_vars), g
        assert list(x.xindexes) == list(y.xindexes) and dict(x.sizes) == dict(y.sizes), g
        same_attrs(x.attrs, y.attrs, g)
        for n in x.variables:
            u, v = x.variables[n], y.variables[n]
            assert type(u) is type(v) and u.dims == v.dims and u.dtype == v.dtype, (g, n)
            assert u.values.tobytes() == v.values.tobytes(), (g, n)
            same_attrs(u.attrs, v.attrs, (g, n))


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Files of every writer: write_posterior, a version-1 file, append_to_posterior, ArviZ's own (xarray's
    h5netcdf store, the writer of old posterior.nc files), and one with strings, scalars, ints and odd groups."""
    import xarray as xr

    root = tmp_path_factory.mktemp("fastpaths")
    idata = _idata(7)
    out = {"posterior": store.write_posterior(idata, root / "posterior.nc")}
    out["version1"] = store.write_netcdf(idata, root / "v1.nc")  # no schema attribute: a version-1 file
    appended = store.write_posterior(idata, root / "appended.nc")
    store.append_to_posterior(appended, posterior_vars={"cutting_kt_pa": np.linspace(1, 2, 60)},
                              groups={"extra": xr.Dataset({"note": ("k", np.array([1.0, 2.0]))})},
                              attrs={"n_cuts": 3, "info": {"a": 1}})
    out["appended"] = appended
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        idata.to_inference_data().to_netcdf(str(root / "arviz.nc"), engine="h5netcdf")
        _arviz().InferenceData(posterior=xr.Dataset({"v": (("chain", "draw", "q"), np.ones((1, 2, 3)))})).to_netcdf(
            str(root / "no_coordinate.nc"), engine="h5netcdf")
    out["arviz"], out["no_coordinate"] = root / "arviz.nc", root / "no_coordinate.nc"
    odd = {"names": (("k",), np.array(["alpha", "b"], dtype=object), {}),
           "k": (("k",), np.array(["x", "yy"], dtype=object), {}),
           "ival": (("k",), np.array([1, 2], dtype=np.int32), {}), "scalar": ((), np.float64(3.5), {}),
           "f32": (("k", "m"), np.arange(6, dtype=np.float32).reshape(2, 3), {}), "m": (("m",), np.arange(3), {}),
           "u8": (("m",), np.arange(3, dtype=np.uint8), {}), "nan": (("m",), np.array([1.0, np.nan, 3.0]), {})}
    post = {"a": (("chain", "draw"), np.zeros((1, 2)), {}), "chain": (("chain",), np.arange(1), {}),
            "draw": (("draw",), np.arange(2), {})}
    netcdf._write_groups({"posterior": netcdf.GroupContent(post, {"x": 1}),
                          "extra_group": netcdf.GroupContent(odd, {"note": "t", "arr": np.array([1.0, 2.0])})},
                         {"root": "r", "n": 3, "vec": np.arange(3), "js": json.dumps({"b": 2})}, root / "odd.nc")
    out["odd"] = root / "odd.nc"
    return out


@pytest.mark.parametrize("name", ["posterior", "version1", "appended", "arviz", "no_coordinate", "odd"])
def test_read_netcdf_reads_what_arviz_reads(files, name):
    path = files[name]
    assert netcdf._read_plain_groups(path) is not None  # the fast path, not the fallback
    _assert_same_inference_data(_arviz().from_netcdf(str(path)), store.read_netcdf(path))


def test_files_outside_the_plain_layout_still_go_to_arviz(tmp_path, monkeypatch):
    import xarray as xr

    # a boolean variable as xarray encodes it (int8 with a dtype attribute): CF decoding, not the plain layout
    path = tmp_path / "encoded.nc"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        _arviz().InferenceData(posterior=xr.Dataset({"ok": (("chain", "draw"), np.array([[True, False]]))})).to_netcdf(
            str(path), engine="h5netcdf")
    with pytest.raises(ValueError):
        netcdf._read_plain_groups(path)
    _assert_same_inference_data(_arviz().from_netcdf(str(path)), store.read_netcdf(path))
    # a file above the in-memory bound stays lazily loaded by ArviZ, with the same content
    big = store.write_posterior(_idata(1), tmp_path / "big.nc")
    monkeypatch.setattr(netcdf, "_EAGER_READ_BYTES", 100)
    assert netcdf._read_plain_groups(big) is None
    _assert_same_inference_data(_arviz().from_netcdf(str(big)), store.read_netcdf(big))
    # an unreadable file fails as ArviZ fails (read_posterior's one line quotes that error)
    junk = tmp_path / "junk.nc"
    junk.write_text("not netCDF\n")
    with pytest.raises(OSError) as want:
        _arviz().from_netcdf(str(junk))
    with pytest.raises(OSError) as got:
        store.read_netcdf(junk)
    assert type(got.value) is type(want.value) and str(got.value) == str(want.value)


def _reference_eigenvalues(h0, frf_x, frf_y):
    """oriented_eigenvalues as it was: the whole array at once (the arithmetic of ``_eigen_parts``), stacked."""
    from bayes_rcsa.stability import zoa

    half_tr, root = zoa._eigen_parts(h0, frf_x, frf_y)
    return np.stack([half_tr + root, half_tr - root], axis=-1)


def _reference_segment_ends(h0, gx, gy):
    mu = _reference_eigenvalues(h0, gx, gy)
    valid = mu.real > 0
    safe = np.where(valid, mu.real, 1.0)
    return np.where(valid, 0.5 / safe, np.inf), np.pi + 2.0 * np.arctan(mu.imag / safe)


def test_blocked_eigenvalues_and_segment_ends_are_the_whole_array_s_bit_for_bit():
    from bayes_rcsa.stability import zoa
    from bayes_rcsa.stability.cutting import CuttingConditions, mean_directional_matrix

    rng = np.random.default_rng(5)
    f = np.linspace(100.0, 1600.0, 701)
    w = 2 * np.pi * f

    def modes(fn, k, zeta):  # two-mode receptances with random natural frequencies: both branches, sign flips
        wn = 2 * np.pi * fn
        return 1 / (k * (1 - (w / wn) ** 2 + 2j * zeta * w / wn)) + 1 / (3 * k * (1 - (w / (1.7 * wn)) ** 2 + 0.04j))

    n = 3 * (zoa._EIGEN_BLOCK_CELLS // f.size) + 7  # several blocks and a partial one
    gx = modes(rng.uniform(400, 900, (n, 1)), 2e7, 0.03)
    gy = modes(rng.uniform(400, 900, (n, 1)), 2.5e7, 0.02)
    for cut in (CuttingConditions(kt=790e6, kr=230e6, flutes=4, milling="down", radial_immersion=0.95),
                CuttingConditions(kt=600e6, kr=300e6, flutes=3, milling="up", radial_immersion=0.3)):
        h0 = mean_directional_matrix(cut)
        for shape in ((n, f.size), (3, n // 3, f.size), (1, f.size)):
            x, y = gx[: int(np.prod(shape[:-1]))].reshape(shape), gy[: int(np.prod(shape[:-1]))].reshape(shape)
            assert zoa.oriented_eigenvalues(h0, x, y).tobytes() == _reference_eigenvalues(h0, x, y).tobytes()
        # broadcasting one FRF against many, as before
        assert zoa.oriented_eigenvalues(h0, gx, gy[0]).tobytes() == _reference_eigenvalues(h0, gx, gy[0]).tobytes()
        got, want = zoa._segment_ends(h0, gx, gy), _reference_segment_ends(h0, gx, gy)
        for g, r in zip(got, want):
            assert g.shape == r.shape and g.tobytes() == r.tobytes()


#: simulate_milling's growth, residual and the samples of periods 8 and 4 for the cases of
#: :func:`test_simulate_milling_gives_the_numbers_of_the_stage_by_stage_version`, as the version that formed every
#: factor in every stage computed them (bit for bit equal to the current one on the development machine; the
#: tolerance leaves room for another BLAS only, far below what a changed formula or delayed value moves).
_SIMULATION_REFERENCE = [
    [[1.0210065142877234, 1.713884550661098], [0.8821756981341903, 1.7787348752085683], [[2.2608339977289388e-06, 5.814895938473287e-06], [0.00019112791892380855, 5.0558716327028116e-05]], [[2.449833567735349e-06, 3.6150267105815388e-06], [-2.9719905275719934e-05, 2.7548760549106045e-05]]],
    [[1.0161854798941254, 1.4294751317252767], [0.8528137913487862, 1.873117500598835], [[2.1218836033904516e-06, 5.637468894248813e-06], [9.697617641881571e-05, -1.6420419112138473e-05]], [[2.2580962164879887e-06, 3.5947401558447978e-06], [-2.691417009057765e-05, 2.7981439299636444e-05]]],
    [[0.7753490293395475, 7.519270730864989], [0.2656166582555554, 1.3516766540181289], [[-6.531656789613126e-06, 4.472071920819956e-06], [-113.62988982919705, -114.74045141019289]], [[-3.842416701096163e-06, 7.788730417523967e-06], [0.002190214540499498, 0.042547174701744586]]],
    [[0.6007880183991753, 1.6367167500938768], [0.07188479396015117, 1.9179395190477853], [[-5.9289207475068985e-06, 4.595400854526895e-06], [0.00032897592952661726, -0.0029478921956151505]], [[-4.894892622019202e-06, 5.858495631622795e-06], [0.0005307164835876093, 0.00017705387636862523]]],
]


def test_simulate_milling_gives_the_numbers_of_the_stage_by_stage_version():
    from bayes_rcsa.stability import CuttingConditions, ModalModel, simulate_milling

    mx = ModalModel([1287.0], [0.02], [1.0e6])
    my = ModalModel([1340.0], [0.03], [1.3e6])
    cuts = [CuttingConditions(kt=790e6, kr=230e6, flutes=4, milling="up", radial_immersion=0.5),
            CuttingConditions(kt=790e6, kr=230e6, flutes=4, radial_immersion=0.7,
                              pitch_angles=tuple(np.radians([80.0, 100.0, 80.0, 100.0])))]  # fractional delays
    got = []
    for cut in cuts:
        for nonlinear in (False, True):
            r = simulate_milling(mx, my, cut, [9000.0, 15000.0], [2e-4, 5e-4], periods=8, nonlinear=nonlinear,
                                 rng=np.random.default_rng(3))
            got.append([r.growth.tolist(), r.residual.tolist(), r.samples[:, -1].tolist(), r.samples[:, 3].tolist()])
    for g, want in zip(got, _SIMULATION_REFERENCE):
        for a, b in zip(g, want):
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=0)


def test_sdm_discretisations_shared_between_calls_give_the_same_limits(monkeypatch):
    from bayes_rcsa.stability import CuttingConditions, ModalModel, sdm

    mx, my = ModalModel([1287.0], [0.02], [1.0e6]), ModalModel([1340.0], [0.03], [1.3e6])
    cuts = [CuttingConditions(kt=790e6, kr=230e6, flutes=4, milling="up", radial_immersion=0.5),
            CuttingConditions(kt=790e6, kr=230e6, flutes=4, radial_immersion=0.7,
                              pitch_angles=tuple(np.radians([80.0, 100.0, 80.0, 100.0])))]
    speeds = np.array([12000.0])

    def limits():
        return [sdm.sdm_depth_limit(mx, my, cut, speeds, (1e-5, 2e-2), intervals=12, rtol=1e-2) for cut in cuts]

    sdm._DISCRETISED.clear()
    shared = limits()
    assert sdm._DISCRETISED  # the searches went through the shared discretisations
    disc = next(iter(sdm._DISCRETISED.values()))[0]
    assert not disc.h_current.flags.writeable  # nobody can change a shared one
    monkeypatch.setattr(sdm, "_discretise", sdm._discretise_uncached)
    for a, b in zip(shared, limits()):
        assert a.tobytes() == b.tobytes()
    # equal cuts of other field types are other keys (a float32 coefficient computes in float32)
    monkeypatch.undo()
    cut = CuttingConditions(kt=np.float32(790e6), kr=230e6, flutes=4, radial_immersion=0.5)
    assert sdm._discretise(cut, 20) is not sdm._discretise(CuttingConditions(kt=790e6, kr=230e6, flutes=4,
                                                                            radial_immersion=0.5), 20)
    assert len(sdm._DISCRETISED) <= sdm._DISCRETISED_MAX


def test_a_small_envelope_runs_compiled_once_the_kernel_is_loaded(monkeypatch):
    from bayes_rcsa.stability import _zoa_kernel, zoa
    from bayes_rcsa.stability.cutting import CuttingConditions, mean_directional_matrix

    f = np.linspace(100.0, 1600.0, 301)
    w = 2 * np.pi * f
    g = 1 / (2e7 * (1 - (w / (2 * np.pi * 700)) ** 2 + 0.06j * w / (2 * np.pi * 700)))
    cut = CuttingConditions(kt=790e6, kr=230e6, flutes=4, milling="down", radial_immersion=0.95)
    ends = zoa._segment_ends(mean_directional_matrix(cut), np.stack([g, 1.1 * g]), np.stack([g, 0.9 * g]))
    speeds = np.array([6000.0, 8000.0, 10000.0, 12000.0, 15000.0, 18000.0])
    K = zoa.lobe_count(f, 4, speeds[0])
    want = zoa._envelope_numpy(*ends, f, 4, speeds, K)
    # the kernel's machine code in this process (as after a large job or the lobes warm-up)
    _zoa_kernel.lower_envelope(np.full((1, 2, 2), np.inf), np.zeros((1, 2, 2)), np.ones(2), np.ones(2), 1, 1,
                               np.ones(2), True, np.full((1, 2), np.inf), np.zeros((1, 1)),
                               np.zeros((1, 1), dtype=np.int64), False)
    assert zoa._compiled_envelope_loaded()
    monkeypatch.setattr(zoa, "_envelope_numpy", None)  # a call of the numpy version would fail
    got = zoa._envelope_of_ends(*ends, f, 4, speeds, K)
    assert np.isfinite(want[0]).any()
    for a, b in zip(got, want):
        assert a.tobytes() == b.tobytes()


def test_a_half_imported_envelope_kernel_counts_as_not_loaded(monkeypatch):
    """A batch or Dask worker thread may look while another thread imports the kernel module (in sys.modules
    before its functions exist): the small job then runs the numpy version, never an AttributeError (a Dask
    batch lost every setup to it once)."""
    import sys
    import types

    from bayes_rcsa.stability import zoa

    monkeypatch.setitem(sys.modules, "bayes_rcsa.stability._zoa_kernel", types.ModuleType("bayes_rcsa.stability._zoa_kernel"))
    assert zoa._compiled_envelope_loaded() is False
