"""ArviZ InferenceData netCDF files: the one writer and reader of the package's ``.nc`` files.

The layout is ArviZ's (one netCDF group per InferenceData group, the
InferenceData's own attributes on the root group), written with h5netcdf
and read by :func:`arviz.from_netcdf`.  Every numeric variable is
zlib-compressed after the byte shuffle (lossless), and the pointwise
log-likelihood is stored in single precision (:data:`LOG_LIKELIHOOD_DTYPE`).

``posterior.nc`` has its own schema on top of this (:mod:`.posterior_file`);
other InferenceData files (a tool library's ``population.nc``) use
:func:`write_netcdf` and :func:`read_netcdf` directly.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Mapping

from ..io.atomic import atomic_write_bytes

__all__ = ["COMPRESSION", "LOG_LIKELIHOOD_DTYPE", "GroupContent", "write_netcdf", "read_netcdf", "read_netcdf_arrays", "ArrayData",
           "ArrayGroup"]

#: Compression of every numeric variable: zlib (lossless) after the byte shuffle, which groups the slowly
#: varying exponent bytes of neighbouring floats and gains ~16 % over zlib alone on the draws.
COMPRESSION = {"zlib": True, "complevel": 4, "shuffle": True}

#: The pointwise log-likelihood (walkers x draws x lines, ~90 % of a posterior.nc) is stored in single precision:
#: relative error 6e-8, i.e. < 2e-6 nats per line for |log p| < 30 and < 2e-3 nats summed over 1000 lines,
#: far below the differences of order 1 nat that LOO/WAIC comparisons read.  Everything else stays float64.
LOG_LIKELIHOOD_DTYPE = "float32"


def _az():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)  # arviz announces its 1.0 refactor on import
        import arviz

    return arviz


class GroupContent:
    """One netCDF group as plain arrays, in file order: what :func:`_write_groups` writes.

    ``variables`` maps each name to ``(dims, values, attrs)`` (coordinates are the variables named after their one
    dimension); ``attrs`` are the group's attributes.  Built from an ``xarray.Dataset`` by :meth:`from_dataset`,
    or directly (identify's writer, which then never imports xarray).
    """

    __slots__ = ("variables", "attrs")

    def __init__(self, variables: Mapping[str, tuple], attrs: Mapping[str, object]):
        self.variables = dict(variables)
        self.attrs = dict(attrs)

    @classmethod
    def from_dataset(cls, dataset) -> "GroupContent":
        # xarray's own write order: the dataset's variables as stored (each coordinate where it was added)
        return cls({n: (tuple(v.dims), v.values, dict(v.attrs)) for n, v in dataset.variables.items()},
                   dataset.attrs)

    def to_dataset(self):
        """The ``xarray.Dataset`` of this group (imports xarray)."""
        import xarray as xr

        coords = {n: xr.Variable(d, v, a) for n, (d, v, a) in self.variables.items() if tuple(d) == (n,)}
        # one DataArray per variable with the coordinates it uses: the Dataset then lists its variables in this
        # content's order (each after the coordinates it brings), as ArviZ's from_dict builds them
        data = {n: xr.DataArray(v, dims=d, coords={k: coords[k] for k in d if k in coords}, attrs=a)
                for n, (d, v, a) in self.variables.items() if tuple(d) != (n,)}
        ds = xr.Dataset(data, attrs=self.attrs)
        unused = {k: c for k, c in coords.items() if k not in ds.variables}
        return ds.assign_coords(unused) if unused else ds


def _write_group(target, content: GroupContent, group: str) -> None:
    """Write one group into an open ``h5netcdf`` group ``target`` as xarray's h5netcdf store does: attributes,
    then the dimensions in order of first use, then each variable (numeric ones compressed as
    :data:`COMPRESSION`, floats with a NaN ``_FillValue``, text as variable-length UTF-8)."""
    import h5py
    import numpy as np

    for k, v in content.attrs.items():
        target.attrs[k] = v
    for dims, values, _ in content.variables.values():
        for dim, size in zip(dims, np.shape(values)):
            if dim not in target.dimensions:
                target.dimensions[dim] = size
    for name, (dims, values, attrs) in content.variables.items():
        values = np.asarray(values)
        kwargs = {}
        kind = values.dtype.kind
        if kind in "fiub":
            if values.ndim:
                kwargs = {"compression": "gzip", "compression_opts": COMPRESSION["complevel"],
                          "shuffle": COMPRESSION["shuffle"]}
            if group == "log_likelihood" and kind == "f" and tuple(dims) != (name,):
                values = values.astype(LOG_LIKELIHOOD_DTYPE)
            dtype = values.dtype
            fill = dtype.type(np.nan) if kind == "f" else None
        else:
            dtype, fill = h5py.special_dtype(vlen=str), None
            values = np.asarray(values, dtype=object)
        var = target.create_variable(name, dimensions=tuple(dims), dtype=dtype, fillvalue=fill, **kwargs)
        for k, v in attrs.items():
            var.attrs[k] = v
        var[...] = values


def _write_groups(groups: Mapping[str, object], root_attrs: Mapping[str, object], path: Path) -> Path:
    """Write ``groups`` (name -> :class:`GroupContent` or xarray.Dataset, in file order) and the root attributes
    atomically.

    The file is built in memory (HDF5's core driver) and written to disk in one piece.  Why: HDF5 crashes the
    process (a segmentation fault in h5py 3.x) when the disk fills while it creates a variable, where a plain
    write raises the :class:`OSError` (ENOSPC) that the command line reports as one line; and xarray's
    ``to_netcdf`` takes a Dask-cluster-wide lock named after its target inside a Dask worker, which a buffer
    cannot name.  Written with h5netcdf the way xarray's h5netcdf store writes (tests/test_store.py compares the
    two files object by object), in ArviZ's layout (one group per InferenceData group), without importing
    xarray, pandas and dask.array for it (about a second of a command's start-up).
    """
    import h5netcdf
    import h5py

    # track_order: groups and attributes keep their creation order, as in files h5netcdf opens itself
    with h5py.File(str(path), "w", driver="core", backing_store=False, track_order=True) as h5:
        # h5netcdf writes its dimension scales and attributes when its wrapper closes; the wrapper leaves the
        # h5py file open, whose image is then complete
        with h5netcdf.File(h5, "w") as f:
            for k, v in root_attrs.items():
                f.attrs[k] = v
            for group, content in groups.items():
                if not isinstance(content, GroupContent):
                    content = GroupContent.from_dataset(content)
                if group == "log_likelihood":
                    content = GroupContent(content.variables, {**content.attrs, "stored_dtype": LOG_LIKELIHOOD_DTYPE})
                _write_group(f.create_group(group), content, group)
        h5.flush()
        image = h5.id.get_file_image()
    atomic_write_bytes(path, image)
    return path


def _groups(idata) -> dict:
    """``{group name: xarray.Dataset or GroupContent}`` of an InferenceData, in its order (the plain contents of
    an object that has them, e.g. :class:`bayes_rcsa.inference.diagnostics.InferenceGroups`)."""
    contents = getattr(idata, "contents", None)
    if isinstance(contents, dict):
        return dict(contents)
    return {g: getattr(idata, g) for g in idata.groups()}


def write_netcdf(idata, path) -> Path:
    """Write ``idata`` to ``path`` atomically (no partial file on failure), compressed.

    Parameters
    ----------
    idata : arviz.InferenceData
    path : path-like

    Returns
    -------
    Path, ``path``

    Notes
    -----
    The pointwise log-likelihood is stored as ``float32`` (recorded in its
    group's ``stored_dtype`` attribute); see :data:`LOG_LIKELIHOOD_DTYPE`.
    A ``posterior.nc`` is written by :func:`bayes_rcsa.store.write_posterior`
    instead, which adds the schema version.
    """
    return _write_groups(_groups(idata), idata.attrs, Path(path))


def read_netcdf(path):
    """Read an InferenceData file written by :func:`write_netcdf` (no checks; see :func:`bayes_rcsa.store.read_posterior`).

    Parameters
    ----------
    path : path-like

    Returns
    -------
    arviz.InferenceData

    Notes
    -----
    The package's own layout (plain compressed arrays with dimension scales, no CF encodings) of up to
    :data:`_EAGER_READ_BYTES` is read at once with h5py (:func:`_read_plain_groups`), which gives the
    groups, variables, dims, coordinates, attributes and dtypes :func:`arviz.from_netcdf` gives, in memory; any
    other file (and any file h5py cannot read as that layout, including a damaged one) goes to
    :func:`arviz.from_netcdf`, lazily loaded, with its errors.
    """
    try:
        plain = _read_plain_groups(path)
    except Exception:  # not the plain layout, or not readable: ArviZ reads it (or raises its own error)
        plain = None
    if plain is None:
        return _az().from_netcdf(str(path))
    groups, attrs = plain
    return _inference_data(groups, attrs)


#: Largest file content (bytes, uncompressed) :func:`read_netcdf` reads into memory at once; larger files stay
#: lazily loaded by ArviZ (a reader that needs one group of a large posterior does not decompress the others).
_EAGER_READ_BYTES = 64 * 2 ** 20

#: The ``NAME`` netCDF gives a dimension scale that is a dimension only (no coordinate values).
_PURE_DIMENSION = "This is a netCDF dimension but not a netCDF variable"


def _plain_variable(ds, group_name: str):
    """``(dims, values)`` of one h5py dataset as xarray's netCDF decoding presents it, or None for a dimension
    without values; :class:`ValueError` for anything the plain layout does not hold (encoded values, attributes
    that CF decoding reads, dimensions of another group, unnamed dimensions)."""
    import h5py
    import numpy as np

    attrs = ds.attrs
    names = [k for k in attrs if k not in _NETCDF_INTERNAL or k == "_FillValue"]
    kind = ds.dtype.kind
    string = h5py.check_string_dtype(ds.dtype)
    if any(k != "_FillValue" for k in names):
        raise ValueError("variable attributes")
    if "_FillValue" in names:
        fill = np.asarray(attrs["_FillValue"])
        if kind != "f" or fill.size != 1 or not np.isnan(fill).all():
            raise ValueError("a fill value that masks values")
    if not (kind in "fiu" or (kind == "O" and string is not None and string.encoding == "utf-8")):
        raise ValueError(f"dtype {ds.dtype}")
    own = ds.name.rsplit("/", 1)[-1]
    if _attribute(attrs.get("CLASS", b"")) == "DIMENSION_SCALE":
        if str(_attribute(attrs.get("NAME", b""))).startswith(_PURE_DIMENSION):
            return None
        if ds.ndim != 1:
            raise ValueError("a dimension scale of several dimensions")
        dims = (own,)
    elif ds.ndim:
        if "DIMENSION_LIST" not in attrs:
            raise ValueError("unnamed dimensions")
        dims = []
        f = ds.file
        for refs in attrs["DIMENSION_LIST"]:
            if len(refs) != 1:
                raise ValueError("several scales on one dimension")
            parent, _, dim = f[refs[0]].name.rpartition("/")
            if parent != group_name:
                raise ValueError("a dimension of another group")
            dims.append(dim)
        dims = tuple(dims)
    else:
        dims = ()
    # netCDF strings: xarray gives fixed-width unicode
    return dims, (np.asarray(ds.asstr()[()], dtype=str) if string is not None else ds[()])


def _read_plain_groups(path):
    """The groups (name -> xarray.Dataset, file order) and root attributes of a file in the package's plain
    layout, read into memory with h5py; None for a file larger than :data:`_EAGER_READ_BYTES` (raises for a
    file not in that layout, see :func:`_plain_variable`)."""
    import h5py
    import xarray as xr

    groups = {}
    with h5py.File(str(path), "r") as f:
        members = [(name, node) for name, node in f.items()]
        if any(isinstance(node, h5py.Dataset) for _, node in members):
            raise ValueError("variables in the root group")
        size = 0
        for name, node in members:
            for child in node.values():
                if not isinstance(child, h5py.Dataset):
                    raise ValueError("nested groups")
                size += child.size * child.dtype.itemsize
        if size > _EAGER_READ_BYTES:
            return None
        for name, node in members:
            data, coords = {}, {}
            for var, ds in node.items():
                got = _plain_variable(ds, node.name)
                if got is None:
                    continue
                dims, values = got
                (coords if dims == (var,) else data)[var] = xr.Variable(dims, values)
            # as xarray's decoding of the group makes it: the data variables in file order, then the variables
            # named after their one dimension, in file order, as (index) coordinates
            groups[name] = xr.Dataset(data, coords=coords, attrs=_attributes(node))
        attrs = _attributes(f)
    return groups, attrs


#: HDF5 attributes that carry netCDF's own bookkeeping (dimension scales, ids), not the file's attributes.
_NETCDF_INTERNAL = ("CLASS", "NAME", "DIMENSION_LIST", "REFERENCE_LIST", "_Netcdf4Coordinates", "_Netcdf4Dimid",
                    "_NCProperties", "_FillValue")


def _attribute(value):
    """An HDF5 attribute as xarray presents it: one-element arrays as scalars, bytes as str."""
    import numpy as np

    if isinstance(value, (bytes, np.bytes_)):
        return value.decode("utf-8")
    if isinstance(value, np.ndarray) and value.ndim == 1 and value.size == 1:
        return value[0]
    return value


def _attributes(node) -> dict:
    # the names first: the bookkeeping attributes are skipped unread (a REFERENCE_LIST of object references
    # takes longer to read than the variable's data)
    attrs = node.attrs
    return {k: _attribute(attrs[k]) for k in attrs if k not in _NETCDF_INTERNAL}


class ArrayVariable:
    """One variable of an :class:`ArrayGroup`: ``values`` (numpy array) and ``attrs``."""

    __slots__ = ("values", "attrs")

    def __init__(self, values, attrs):
        self.values = values
        self.attrs = attrs


class ArrayGroup:
    """One group of a netCDF file as numpy arrays: what the readers of a ``posterior.nc`` use of an
    ``xarray.Dataset`` (``data_vars``, ``ds[name].values``, ``attrs``), without importing xarray.

    Attributes
    ----------
    data_vars : dict of str to ArrayVariable, the group's variables other than its coordinates
    coords : dict of str to ArrayVariable, the coordinate (dimension-scale) variables
    attrs : dict, the group's attributes
    """

    def __init__(self, data_vars: dict, coords: dict, attrs: dict):
        self.data_vars = data_vars
        self.coords = coords
        self.attrs = attrs

    def __getitem__(self, name: str) -> ArrayVariable:
        return self.data_vars[name] if name in self.data_vars else self.coords[name]

    def __contains__(self, name: str) -> bool:
        return name in self.data_vars or name in self.coords


class ArrayData:
    """A netCDF InferenceData file read as numpy arrays: ``attrs``, ``groups()`` and one :class:`ArrayGroup`
    attribute per group (``None`` for a group the file lacks), duck-typed to the parts of an
    ``arviz.InferenceData`` that reading draws needs."""

    def __init__(self, groups: dict, attrs: dict):
        self._groups = groups
        self.attrs = attrs

    def groups(self) -> list[str]:
        return list(self._groups)

    def __getattr__(self, name: str):
        if name.startswith("_"):
            raise AttributeError(name)
        return self._groups.get(name)


def read_netcdf_arrays(path, groups=None) -> ArrayData:
    """Read the numeric content of an InferenceData file written by :func:`write_netcdf` with h5py only.

    ``arviz.from_netcdf`` imports ArviZ, xarray, pandas and scipy.stats (seconds of start-up on the development
    machine); a command that only needs the draws (posterior-mode lobes, predict) reads them here instead.  The
    values are the same: the files hold plain (compressed) arrays with no scale, offset or time encoding.

    Parameters
    ----------
    path : path-like
    groups : sequence of str, optional, the groups to read (default: all)

    Returns
    -------
    ArrayData
    """
    import h5py
    import numpy as np

    out = {}
    with h5py.File(str(path), "r") as f:
        for name, group in f.items():
            if not isinstance(group, h5py.Group) or (groups is not None and name not in groups):
                continue
            data_vars, coords = {}, {}
            for var, ds in group.items():
                if not isinstance(ds, h5py.Dataset):
                    continue
                values = ds[()]
                if values.dtype.kind in "OS":  # netCDF strings: xarray gives fixed-width unicode
                    values = np.asarray(ds.asstr()[()], dtype=str)
                is_scale = _attribute(ds.attrs.get("CLASS", b"")) == "DIMENSION_SCALE"
                (coords if is_scale else data_vars)[var] = ArrayVariable(values, _attributes(ds))
            out[name] = ArrayGroup(data_vars, coords, _attributes(group))
        attrs = _attributes(f)
    return ArrayData(out, attrs)


def _inference_data(groups: Mapping[str, object], attrs: Mapping[str, object]):
    """An :class:`arviz.InferenceData` of ``groups`` (name -> xarray.Dataset) with root attributes ``attrs``."""
    return _az().InferenceData(attrs=dict(attrs), **dict(groups))
