# SPDX-License-Identifier: GPL-3.0-or-later

"""What Blender stores and draws for PCVR: the settings (properties.py), the panels (panels.py), the operators
(operators.py) and the transfer-function presets (presets.py; the shipped ones are in the add-on's presets/
folder). The add-on's register() registers them."""
