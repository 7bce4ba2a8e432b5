"""Writes the small layered PSD the editor's e2e test opens (made with psd-tools).

Bottom to top: 'sky' (opaque blue, the whole canvas), a group 'figure' at 50 % opacity
holding 'arm' (red, 8x6 at (10, 5), blend mode Multiply), and 'notes' (hidden, green).
"""

import sys

from PIL import Image
from psd_tools import PSDImage
from psd_tools.api.layers import Group, PixelLayer
from psd_tools.constants import BlendMode

psd = PSDImage.new("RGB", (32, 24))
sky = PixelLayer.frompil(Image.new("RGBA", (32, 24), (20, 40, 200, 255)), psd, "sky", 0, 0)
psd.append(sky)
arm = PixelLayer.frompil(Image.new("RGBA", (8, 6), (220, 30, 10, 255)), psd, "arm", 5, 10)
psd.append(arm)
arm.blend_mode = BlendMode.MULTIPLY
group = Group.group_layers(psd, [arm], name="figure")
group.opacity = 128
notes = PixelLayer.frompil(Image.new("RGBA", (32, 24), (0, 200, 0, 255)), psd, "notes", 0, 0)
psd.append(notes)
notes.visible = False
psd.save(sys.argv[1])
