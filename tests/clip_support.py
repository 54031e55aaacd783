"""Whether pcvr_native clips (issue 21): the tests of clipping that render need it, and say so when they skip."""

import pcvr_native as pn
import pytest

# render_xray, render_shaded and render_mip take clip_box and clip_planes (their signatures say so).
NATIVE_CLIPPING = all("clip_box" in function.__doc__ and "clip_planes" in function.__doc__
                      for function in (pn.render_xray, pn.render_shaded, pn.render_mip))
needs_native_clipping = pytest.mark.skipif(
    not NATIVE_CLIPPING, reason="pcvr_native's render functions lack the clip_box and clip_planes keywords")
