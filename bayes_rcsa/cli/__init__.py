"""The ``bayes-rcsa`` command line: one module per sub-command, each only parsing, calling and printing.

Every sub-command module has ``register(subparsers)`` (its options and help)
and ``run(args) -> Summary``: it turns option strings into numbers
(:mod:`._common`, :mod:`._arguments`), calls one function of
:mod:`bayes_rcsa.workflows`, saves the result into ``--out`` and returns the
one line (and the ``--json`` facts) that :mod:`.main` prints.  Bad input is
one line on stderr and exit status 2 (:func:`.main.main`).
"""
