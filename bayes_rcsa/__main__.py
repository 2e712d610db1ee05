"""``python -m bayes_rcsa``: the same as the ``bayes-rcsa`` command."""

import sys

from .cli.main import main

sys.exit(main())
