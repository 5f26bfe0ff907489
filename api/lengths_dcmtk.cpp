// lengths_dcmtk.cpp - the walk over a DICOM object's element lengths that comes before DCMTK reads
// it (dicom_lengths.h). Written by hand: DCMTK has no read that refuses a length over what the
// buffer holds before allocating it; the walk uses its dictionary for implicit-VR sequences.
#include "dicom_lengths.h"

#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dctk.h>

#include <cstring>

/* Lengths are read little endian: a data set the meta header says is big endian
 * (1.2.840.10008.1.2.2, retired) is left to DCMTK. */
extern "C" bool dicom_lengths_fit(const void *data, size_t n)
{
    const unsigned char *b = (const unsigned char *)data;
    auto u16 = [&](size_t at) { return (unsigned)b[at] | (unsigned)b[at + 1] << 8; };
    auto u32 = [&](size_t at) { return (size_t)u16(at) | (size_t)u16(at + 2) << 16; };
    auto vr_at = [&](size_t at) { return at + 6 <= n && b[at + 4] >= 'A' && b[at + 4] <= 'Z' && b[at + 5] >= 'A' && b[at + 5] <= 'Z'; };
    auto long_vr = [&](size_t at) {
        char vr[3] = {(char)b[at + 4], (char)b[at + 5], 0};
        return strstr("OB OD OF OL OV OW SQ SV UC UN UR UT UV", vr) != nullptr;
    };
    size_t at = n >= 132 && !memcmp(b + 128, "DICM", 4) ? 132 : n >= 4 && !memcmp(b, "DICM", 4) ? 4 : 0;
    bool implicit = false, meta = at > 0, big_endian = false;
    if (!meta)
        implicit = !vr_at(0);
    for (int steps = 0; at + 8 <= n && steps < 1000000; steps++) {
        unsigned group = u16(at), elem = u16(at + 2);
        bool in_meta = meta && group == 0x0002;
        if (meta && !in_meta) { /* the data set starts */
            if (big_endian)
                return true;
            meta = false;
            implicit = !vr_at(at);
        }
        if (group == 0xfffe) { /* items and delimiters: tag and a 4-byte length, always */
            size_t len = u32(at + 4);
            at += 8;
            if (elem == 0xe000 || len == 0xffffffffu || len == 0)
                continue; /* step into an item */
            if (len > n - at)
                return false;
            at += len;
            continue;
        }
        size_t head, len;
        bool sq;
        if (!implicit || in_meta) {
            if (!vr_at(at))
                return true; /* not what this walk reads: DCMTK says what it is */
            bool lv = long_vr(at);
            head = lv ? 12 : 8;
            if (at + head > n)
                return false;
            len = lv ? u32(at + 8) : u16(at + 6);
            sq = b[at + 4] == 'S' && b[at + 5] == 'Q';
        } else {
            head = 8;
            len = u32(at + 4);
            sq = DcmTag((Uint16)group, (Uint16)elem).getEVR() == EVR_SQ;
        }
        if (in_meta && elem == 0x0010 && len >= 19 && at + head + len <= n) /* the transfer syntax */
            big_endian = !memcmp(b + at + head, "1.2.840.10008.1.2.2", 19) && (len == 19 || b[at + head + 19] <= ' ');
        at += head;
        if (len == 0xffffffffu || sq)
            continue; /* step into an undefined length or a sequence */
        if (len > n - at)
            return false;
        at += len;
    }
    return true;
}

