#!/usr/bin/env python3
"""png_cover.py FILE.png: the fraction of a PNG's pixels that differ from its top-left pixel (the
background), printed; an 8-bit RGB or RGBA PNG as surfd writes it, decoded with zlib alone."""
import struct
import sys
import zlib

data = open(sys.argv[1], "rb").read()
if data[:8] != b"\x89PNG\r\n\x1a\n":
    sys.exit("not a PNG")
at, idat, w = 8, b"", 0
while at < len(data):
    n, kind = struct.unpack_from(">I4s", data, at)
    body = data[at + 8:at + 8 + n]
    if kind == b"IHDR":
        w, h, depth, color = struct.unpack_from(">IIBB", body)
        if depth != 8 or color not in (2, 6):
            sys.exit("8-bit RGB or RGBA only")
        bpp = 3 if color == 2 else 4
    elif kind == b"IDAT":
        idat += body
    at += 12 + n
raw, rows, prev = zlib.decompress(idat), [], bytearray(w * bpp)
for y in range(h):
    f, line = raw[y * (w * bpp + 1)], bytearray(raw[y * (w * bpp + 1) + 1:(y + 1) * (w * bpp + 1)])
    for i in range(len(line)):
        a = line[i - bpp] if i >= bpp else 0
        b, c = prev[i], prev[i - bpp] if i >= bpp else 0
        p = a + b - c
        pred = (0, a, b, (a + b) // 2, a if abs(p - a) <= abs(p - b) and abs(p - a) <= abs(p - c) else b if abs(p - b) <= abs(p - c) else c)[f]
        line[i] = (line[i] + pred) & 255
    rows.append(line)
    prev = line
bg = bytes(rows[0][:3])
covered = sum(1 for line in rows for x in range(w) if bytes(line[x * bpp:x * bpp + 3]) != bg)
print("%.4f" % (covered / (w * h)))
