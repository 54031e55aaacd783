# SPDX-License-Identifier: GPL-3.0-or-later

"""Prepare, render, finish: the stages of an F12 render (engine.py) and of the viewport's renders on a worker
thread (viewport_session.py, viewport.py, drawn by viewport_draw.py), the grid cache they share, and the
statistics the user reads of them."""
