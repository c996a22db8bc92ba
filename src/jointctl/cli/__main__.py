"""``python -m jointctl.cli``: the ``jointctl`` command."""

import sys

from jointctl.cli import main

sys.exit(main())
