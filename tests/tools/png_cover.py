#!/usr/bin/env python3
"""png_cover.py FILE.png: the fraction of a PNG's pixels that differ from its top-left pixel (the
background), printed."""
import sys

import png_read

w, h, rows = png_read.read(sys.argv[1])
bg = rows[0][0]
print("%.4f" % (sum(1 for line in rows for px in line if px != bg) / (w * h)))
