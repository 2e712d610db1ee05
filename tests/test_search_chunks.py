"""The start search's likelihood maps do not depend on how the grid is cut into chunks.

The grid is evaluated in cache-sized chunks for speed (inference/search.py); every grid point's arithmetic is
the same in any chunk, so the maps must be equal bit for bit, or the starts (and every posterior after them)
would depend on a performance setting.
"""

from __future__ import annotations

import numpy as np

import bayes_rcsa.inference.search as search
from bayes_rcsa import identify
from bayes_rcsa.data import example_dir


def test_maps_are_bit_identical_whatever_the_chunk(monkeypatch, tmp_path):
    calls = []
    original = search._length_maps

    def recording(*args, **kwargs):
        out = original(*args, **kwargs)
        calls.append((args, kwargs, out))
        return out

    monkeypatch.setattr(search, "_length_maps", recording)
    identify(example_dir() / "setup.toml", lengths=(0.03,), method="deterministic", plots=False)
    assert calls
    args, kwargs, default = calls[0]
    n_points = args[1].size * args[2].size
    assert n_points > 3 * 1024  # the default chunk really cuts this grid
    for chunk in (97, n_points):  # an odd-sized chunk, one chunk for all
        other = original(*args, **{**kwargs, "chunk_sets": chunk})
        assert other.keys() == default.keys()
        for length in default:
            assert np.array_equal(other[length], default[length]), (chunk, length)
