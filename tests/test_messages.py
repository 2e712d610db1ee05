"""The warning log keeps the package's own warnings whatever the process-global warnings state does.

Before Python 3.14 ``warnings.catch_warnings`` saves and restores the process's ``showwarning`` and filters;
another thread entering it while a workflow runs can put back a stale ``showwarning`` (a CI run lost a
geometry warning that way).  :func:`bayes_rcsa.messages.warn` records the line in the open logs before
``warnings.warn`` sees it; these tests replace ``showwarning`` and the filters from inside a log, as such a
thread would, and would fail if the package's warnings reached the log only through the hook.
"""

from __future__ import annotations

import warnings

from bayes_rcsa import messages
from bayes_rcsa.errors import DataWarning
from bayes_rcsa.messages import warning_log


def test_own_warning_is_recorded_when_showwarning_is_replaced_meanwhile():
    with warning_log(echo=False) as log:
        warnings.showwarning = lambda *a, **k: None  # a stale hook put back by another thread
        messages.warn("setup.toml: tools.tool.diameter = 0.0078 differs", DataWarning)
        warnings.warn("overflow in a third-party routine", RuntimeWarning)  # reaches the log only through the hook
    assert log == ["setup.toml: tools.tool.diameter = 0.0078 differs"]


def test_own_warning_is_recorded_under_an_ignore_filter():
    with warning_log(echo=False) as log, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a filter list left behind by another thread's block
        messages.warn("file.csv: 3 lines   with\nnegative frequency", DataWarning)
    assert log == ["file.csv: 3 lines with negative frequency"]  # stored as one line


def test_echo_shows_each_own_warning_once_and_logs_nest():
    shown = []
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = lambda message, *a, **k: shown.append(str(message))
        with warning_log(echo=True) as outer:
            messages.warn("first", DataWarning)
            with warning_log() as inner:
                messages.warn("second", DataWarning)
                messages.warn("first", DataWarning)  # already in the outer log: not shown again
            warnings.warn("third", UserWarning)
    assert shown == ["first", "second", "third"]
    assert outer == ["first", "second", "third"] and inner == ["second", "first"]
    assert messages._UNSHOWN == set()


def test_warn_outside_any_log_is_a_plain_warning():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        messages.warn("no log open", DataWarning)
    assert [str(w.message) for w in caught] == ["no log open"] and caught[0].category is DataWarning
    assert caught[0].filename == __file__  # stacklevel counts from the caller
