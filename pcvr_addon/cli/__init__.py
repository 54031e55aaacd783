# SPDX-License-Identifier: GPL-3.0-or-later

"""The command line, `python -m pcvr_addon render|convert ...`: its parser and `render` (main.py), `convert` and
the scans that `render` converts first (convert_command.py), and the scene it renders (command_scene.py, which the
batches in batch/ make too)."""
