"""The bounded cache shared by the computations that are asked again with the same inputs."""

from __future__ import annotations

import threading

import pytest

from bayes_rcsa.caching import BoundedCache


def test_the_oldest_entry_goes_first_and_the_size_stays_bounded():
    cache = BoundedCache(2)
    cache.put("a", 1)
    cache.put("b", 2)
    assert cache.put("c", 3) == 3
    assert "a" not in cache and cache.get("b") == 2 and cache.get("c") == 3 and len(cache) == 2
    cache.put("b", 20)  # a stored key is replaced, not duplicated
    assert cache.values() == [3, 20]
    assert cache.get("missing", "default") == "default"
    cache.clear()
    assert len(cache) == 0


def test_threads_sharing_it_keep_it_bounded_and_consistent():
    cache = BoundedCache(8)

    def fill(offset):
        for i in range(2000):
            cache.put((offset, i), i)
            cache.get((offset, i - 1))

    threads = [threading.Thread(target=fill, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(cache) == 8


def test_a_size_below_one_is_refused():
    with pytest.raises(ValueError, match="maxsize = 0"):
        BoundedCache(0)
