# SPDX-License-Identifier: GPL-3.0-or-later

"""python -m pcvr_addon render|convert INPUT -o OUTPUT [options]; see cli.py."""

import sys

from .cli import main

sys.exit(main())
