"""``python -m bench``: the same entry point as the installed ``bench`` command (for a checkout without the
console script on PATH, or a Python other than the one the script was installed for)."""

import sys

from bench.cli import main

sys.exit(main())
