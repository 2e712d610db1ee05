"""Setups on threads of one process print into their own logs (bayes_rcsa.batch.streams).

With the process-wide ``contextlib.redirect_stdout/stderr`` the batch used before, two setups running at once
on threads crossed their lines, and the thread finishing last restored the other's (closed) log file as the
process's stderr.  Here two threads print alternately, in lock step, while the main thread prints too.
"""

from __future__ import annotations

import io
import sys
import threading

from bayes_rcsa.batch.streams import output_to


def test_two_threads_print_into_their_own_logs_and_the_streams_come_back():
    before = sys.stdout, sys.stderr
    logs = {name: io.StringIO() for name in ("a", "b")}
    # both threads are inside their blocks before either prints, and they alternate line by line
    barrier = threading.Barrier(2)
    turns = {"a": threading.Semaphore(1), "b": threading.Semaphore(0)}
    other = {"a": "b", "b": "a"}

    def setup(name):
        with output_to(logs[name]):
            barrier.wait()
            for i in range(50):
                turns[name].acquire()
                print(f"{name} out {i}")
                print(f"{name} err {i}", file=sys.stderr)
                turns[other[name]].release()
            barrier.wait()  # neither leaves while the other still prints

    main_lines = io.StringIO()
    sys.stdout = main_lines  # what the caller had in place (as capsys would): the main thread keeps it
    try:
        threads = [threading.Thread(target=setup, args=(n,)) for n in logs]
        for t in threads:
            t.start()
        print("main thread line")
        for t in threads:
            t.join(30)
        assert sys.stdout is main_lines and sys.stderr is before[1]
    finally:
        sys.stdout = before[0]
    for name, log in logs.items():
        lines = log.getvalue().splitlines()
        assert len(lines) == 100
        assert all(line.startswith(name + " ") for line in lines), lines[:4]
        assert lines[:2] == [f"{name} out 0", f"{name} err 0"]
    assert main_lines.getvalue() == "main thread line\n"


def test_a_stream_replaced_meanwhile_is_left_in_place():
    before = sys.stderr
    mine = io.StringIO()
    try:
        with output_to(io.StringIO()):
            sys.stderr = mine  # e.g. a test framework capturing again
        assert sys.stderr is mine
    finally:
        sys.stderr = before
