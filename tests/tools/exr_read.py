#!/usr/bin/env python3
"""exr_read.py: an OpenEXR image as surfd writes it (scanline, ZIP compression, float or half
channels), decoded with zlib alone - the tests read surfd's EXR back without a library of its own.

  exr_read.py FILE.exr        prints the channels, and per channel its least and greatest value
Imported: read(path) -> (width, height, {channel: [values, row by row from the top]})."""
import struct
import sys
import zlib


def _attrs(data):
    at, attrs = 8, {}
    while data[at] != 0:
        name_end = data.index(b"\0", at)
        type_end = data.index(b"\0", name_end + 1)
        size = struct.unpack_from("<i", data, type_end + 1)[0]
        attrs[data[at:name_end].decode()] = (data[name_end + 1:type_end].decode(), data[type_end + 5:type_end + 5 + size])
        at = type_end + 5 + size
    return attrs, at + 1


def read(path):
    data = open(path, "rb").read()
    if data[:4] != b"\x76\x2f\x31\x01":
        raise SystemExit("%s: not OpenEXR" % path)
    attrs, at = _attrs(data)
    if attrs["compression"][1][0] not in (0, 3):  # none or ZIP (16 lines a block)
        raise SystemExit("%s: compression %d not read here" % (path, attrs["compression"][1][0]))
    lines_per_block = 16 if attrs["compression"][1][0] == 3 else 1
    x0, y0, x1, y1 = struct.unpack("<4i", attrs["dataWindow"][1])
    w, h = x1 - x0 + 1, y1 - y0 + 1
    chans, c = [], attrs["channels"][1]
    while c[0] != 0:
        end = c.index(b"\0")
        kind = struct.unpack_from("<i", c, end + 1)[0]  # 0 uint, 1 half, 2 float
        chans.append((c[:end].decode(), kind))
        c = c[end + 17:]
    size = {0: 4, 1: 2, 2: 4}
    n_blocks = (h + lines_per_block - 1) // lines_per_block
    offsets = struct.unpack_from("<%dQ" % n_blocks, data, at)
    out = {name: [0.0] * (w * h) for name, _ in chans}
    for off in offsets:
        y, n = struct.unpack_from("<ii", data, off)
        raw = data[off + 8:off + 8 + n]
        lines = min(lines_per_block, y1 + 1 - y)
        expect = lines * w * sum(size[k] for _, k in chans)
        if n < expect:  # compressed: zlib, then the predictor and the interleaving undone
            t = bytearray(zlib.decompress(raw))
            for i in range(1, len(t)):
                t[i] = (t[i - 1] + t[i] - 128) & 0xFF
            half = (len(t) + 1) // 2
            raw = bytearray(len(t))
            raw[0::2], raw[1::2] = t[:half], t[half:]
        pos = 0
        for line in range(lines):
            row = (y - y0 + line) * w
            for name, kind in chans:
                fmt = {0: "<%dI", 1: "<%de", 2: "<%df"}[kind] % w
                out[name][row:row + w] = struct.unpack_from(fmt, raw, pos)
                pos += w * size[kind]
    return w, h, out


if __name__ == "__main__":
    w, h, ch = read(sys.argv[1])
    print("%d x %d" % (w, h))
    for name in sorted(ch):
        v = [x for x in ch[name] if x == x]
        print("%-6s %g .. %g" % (name, min(v), max(v)))
