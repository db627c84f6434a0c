"""``python -m rmac_mj.cli``: the ``rmac-mj`` command."""

import sys

from rmac_mj.cli import main

sys.exit(main())
