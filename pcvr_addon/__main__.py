# SPDX-License-Identifier: GPL-3.0-or-later

"""python -m pcvr_addon render|convert INPUT -o OUTPUT [options]; see cli/main.py."""

import sys

from .cli.main import main

# Guarded: the worker processes of a local Dask cluster (--workers) import this module again as they start.
if __name__ == "__main__":
    sys.exit(main())
