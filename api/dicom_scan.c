/* dicom_scan.c - the pass over a DICOM object's structure that comes before DCMTK (dicom_scan.h).
 * It reads what DCMTK's reader would: the meta header (explicit VR little endian), then the data
 * set in the transfer syntax the header names (or, without one, as its first element looks, as
 * DCMTK guesses), stepping into sequences and items with a stack of its own (never recursion)
 * and over every other value, so its cost is one look at each element. It must not accept what
 * DCMTK would read deeper or longer than the caps say. */
#include "dicom_scan.h"

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define UNDEFINED 0xffffffffu /* an undefined length */

enum frame_kind {
    F_DATASET, /* the top: elements up to the end of the buffer */
    F_SEQ,     /* a sequence: items, up to its end or its delimiter */
    F_ITEM,    /* an item's data set: elements, up to its end or its delimiter */
    F_FRAGS,   /* encapsulated pixel data: fragment items, up to its delimiter */
};

struct frame {
    enum frame_kind kind;
    size_t end;          /* where a defined length ends; the parent's end when undefined */
    bool undefined;      /* ends at a delimiter */
    bool implicit;       /* implicit VR inside */
    bool big;            /* big endian inside */
    bool tentative;      /* an implicit VR value taken for a sequence because it starts with an item */
    uint32_t max_tag;    /* greatest tag read in this data set or item */
    int n_creators;      /* private creators read in it */
    bool blank;          /* dicom_blank_identity: every value inside is blanked (an identifying sequence) */
    size_t start;        /* a tentative sequence's value: stepped over whole when it was not a sequence */
    struct dicom_scan_stats s; /* ... and counted as one element: the counts before its inside was read */
};

/* the stack: the top data set, then up to DICOM_MAX_DEPTH sequences, each with its item or
 * fragment list (+1: the sequence past the cap is pushed, then refused) */
#define STACK_MAX (2 * DICOM_MAX_DEPTH + 3)

struct scan {
    const unsigned char *b;
    unsigned char *w;    /* dicom_blank_identity: b, writable; NULL for dicom_scan */
    size_t n_blanked;
    /* dicom_blank_identity walks twice: the first notes where the values taken for sequences were
     * not one (ascending: a fault resumes past its value), so that the second, which blanks, knows
     * each value's structure before it writes anything inside */
    size_t *not_seq, n_not_seq, cap_not_seq, next_not_seq;
    bool note_not_seq;
    size_t n, at;
    struct frame st[STACK_MAX];
    int top;             /* st[top] is the innermost frame */
    int depth;           /* sequences open */
    struct dicom_scan_stats s;
    const char *pointer;
    struct sf_err *err;
};

static unsigned u16(const struct scan *c, size_t at, bool big)
{
    return big ? (unsigned)c->b[at] << 8 | c->b[at + 1] : (unsigned)c->b[at] | (unsigned)c->b[at + 1] << 8;
}

static uint32_t u32(const struct scan *c, size_t at, bool big)
{
    return big ? (uint32_t)u16(c, at, true) << 16 | u16(c, at + 2, true) : u16(c, at, false) | (uint32_t)u16(c, at + 2, false) << 16;
}

/* The VRs of PS3.5 6.2; those with a 4-byte length after two reserved bytes in explicit VR. */
static const char VRS[] = "AEASATCSDADSDTFDFLISLOLTOBODOFOLOVOWPNSHSLSQSSSTSVTMUCUIULUNURUSUTUV";
static const char LONG_VRS[] = "OBODOFOLOVOWSQSVUCUNURUTUV";

static bool vr_in(const unsigned char *vr, const char *list)
{
    for (const char *p = list; *p; p += 2)
        if (p[0] == (char)vr[0] && p[1] == (char)vr[1])
            return true;
    return false;
}

static int fail(struct scan *c, int code, const char *what, uint32_t tag)
{
    return sf_fail(c->err, code, c->pointer, "%s (element (%04X,%04X) at byte %zu)", what, (unsigned)(tag >> 16),
                   (unsigned)(tag & 0xffff), c->at);
}

/* ---- dicom_blank_identity: the PS3.15 basic profile's identifying elements, blanked ---- */

/* The basic application level confidentiality profile's (PS3.15 E.1-1) elements that name or
 * describe the patient, the people and places of their care, and when it happened, sorted. Every
 * person's name the table lists is here, with its identification sequence: those of the study
 * (referring, consulting, performing, reading physicians, physicians of record, operators), a
 * Segmentation's and a presentation's Content Creator's Name (0070,0084, Type 2 in every SEG),
 * an RT object's Reviewer Name (300E,0008), a report's observers and participants, and the
 * retired results' authors. UIDs are kept (its Retain UIDs option: the series, its frame of
 * reference and the structure sets made from it must still refer to each other), as are the
 * geometry and the pixel data. */
static const uint32_t IDENTIFYING[] = {
    0x00080020, 0x00080021, 0x00080022, 0x00080023, 0x00080024, 0x00080025, 0x0008002a, 0x00080030, 0x00080031,
    0x00080032, 0x00080033, 0x00080034, 0x00080035, 0x00080050, 0x00080080, 0x00080081, 0x00080082, 0x00080090,
    0x00080092, 0x00080094, 0x00080096, 0x0008009c, 0x0008009d, 0x00081010, 0x00081030, 0x0008103e, 0x00081040,
    0x00081048, 0x00081049, 0x00081050, 0x00081052, 0x00081060, 0x00081062, 0x00081070, 0x00081072, 0x00081080,
    0x00081084, 0x00081120, 0x00084000, 0x00100010, 0x00100020, 0x00100021, 0x00100030, 0x00100032, 0x00100040,
    0x00100050, 0x00100101, 0x00100102, 0x00101000, 0x00101001, 0x00101002, 0x00101005, 0x00101010, 0x00101020,
    0x00101030, 0x00101040, 0x00101050, 0x00101060, 0x00101080, 0x00101081, 0x00101090, 0x00102000, 0x00102110,
    0x00102150, 0x00102152, 0x00102154, 0x00102160, 0x00102180, 0x001021a0, 0x001021b0, 0x001021c0, 0x001021d0,
    0x001021f0, 0x00102297, 0x00102299, 0x00104000, 0x00181000, 0x00181030, 0x00200010, 0x00204000, 0x00321032,
    0x00321033, 0x00321060, 0x00321070, 0x00324000, 0x00380010, 0x00380011, 0x00380300, 0x00380400, 0x00380500,
    0x00384000, 0x00400006, 0x0040000b, 0x00400241, 0x00400242, 0x00400243, 0x00400244, 0x00400245, 0x00400253,
    0x00400254, 0x00400275, 0x00401001, 0x00401010, 0x00401011, 0x00401101, 0x00401102, 0x00401103, 0x00401104,
    0x00402008, 0x00402016, 0x00402017, 0x00404034, 0x00404035, 0x00404036, 0x00404037, 0x0040a073, 0x0040a075,
    0x0040a078, 0x0040a07a, 0x0040a088, 0x0040a123, 0x0040a307, 0x0040a352, 0x0040a730, 0x00700084, 0x00700086,
    0x00880910, 0x30060002, 0x30060004, 0x30060008, 0x30060009, 0x300e0008, 0x40080102, 0x4008010a, 0x4008010c,
    0x40080111, 0x40080114, 0x40080119,
};

/* Whether tag is blanked. Private elements are (the profile removes them: vendors keep names and
 * dates there); their creators are kept. */
static bool identifying(uint32_t tag)
{
    bool private = (tag >> 16 & 1) && (tag & 0xffff) >= 0x1000;
    size_t lo = 0, hi = sizeof IDENTIFYING / sizeof *IDENTIFYING;
    while (!private && lo < hi) {
        size_t mid = (lo + hi) / 2;
        if (IDENTIFYING[mid] < tag)
            lo = mid + 1;
        else
            hi = mid;
    }
    return private || (lo < sizeof IDENTIFYING / sizeof *IDENTIFYING && IDENTIFYING[lo] == tag);
}

/* What a blanked value is filled with: text with spaces (an empty value, padded, to DCMTK), others
 * with zeros; in implicit VR (vr NULL), the listed public elements are text, private ones unknown. */
static unsigned char fill_for(uint32_t tag, const unsigned char *vr)
{
    if (vr)
        return vr_in(vr, "AEASCSDADSDTISLOLTPNSHSTTMUCURUT") ? ' ' : 0;
    return tag >> 16 & 1 ? 0 : ' ';
}

static void blank(struct scan *c, size_t at, size_t len, unsigned char fill)
{
    memset(c->w + at, fill, len);
    c->n_blanked++;
}

/* A structural fault: inside a tentative sequence, the value was not a sequence after all and is
 * stepped over whole (as DCMTK would read it without a dictionary entry saying SQ), counted as
 * one element; else refused. */
static int fault(struct scan *c, const char *what, uint32_t tag)
{
    for (int k = c->top; k > 0; k--)
        if (c->st[k].tentative) {
            if (c->note_not_seq) {
                if (c->n_not_seq == c->cap_not_seq) {
                    size_t cap = c->cap_not_seq ? 2 * c->cap_not_seq : 64;
                    size_t *p = realloc(c->not_seq, cap * sizeof *p);
                    if (!p)
                        return sf_fail(c->err, SF_ENOMEM, c->pointer, "out of memory");
                    c->not_seq = p, c->cap_not_seq = cap;
                }
                c->not_seq[c->n_not_seq++] = c->st[k].start;
            }
            c->at = c->st[k].end;
            c->s = c->st[k].s;
            for (int j = c->top; j >= k; j--)
                if (c->st[j].kind == F_SEQ || c->st[j].kind == F_FRAGS)
                    c->depth--;
            c->top = k - 1;
            return 0;
        }
    char msg[160];
    snprintf(msg, sizeof msg, "not a readable DICOM object: %s", what);
    return fail(c, SF_EFORMAT, msg, tag);
}

static int push(struct scan *c, enum frame_kind kind, size_t len, bool implicit, bool big, bool tentative,
                bool blank, uint32_t tag)
{
    const struct frame *p = &c->st[c->top];
    struct frame f = {.kind = kind, .implicit = implicit, .big = big, .tentative = tentative, .start = c->at,
                      .blank = kind != F_FRAGS && (p->blank || blank), .s = c->s};
    if (kind == F_SEQ || kind == F_FRAGS) {
        if (++c->depth > DICOM_MAX_DEPTH) {
            char what[64];
            snprintf(what, sizeof what, "sequences nested deeper than %d", DICOM_MAX_DEPTH);
            return fail(c, SF_ELIMIT, what, tag);
        }
        if (c->depth > c->s.max_depth)
            c->s.max_depth = c->depth;
    }
    f.undefined = len == UNDEFINED;
    f.end = f.undefined ? p->end : c->at + len;
    c->st[++c->top] = f;
    return 0;
}

/* How the data set is encoded when no meta header says it, from its first element: explicit when
 * a VR follows the tag; big endian when the tag reads as a public group only byte-swapped. DCMTK
 * guesses otherwise (from its dictionary), so the readers tell it this guess (dcmtk_in.h). */
static void guess_syntax(struct scan *c, size_t at, bool *implicit, bool *big)
{
    *implicit = !(at + 6 <= c->n && vr_in(c->b + at + 4, VRS));
    unsigned le = at + 2 <= c->n ? u16(c, at, false) : 0;
    *big = (le & 0xff) == 0 && le >> 8 >= 0x02 && le >> 8 <= 0x7f && !(le >> 8 & 1);
}

/* Reads the meta header from c->at (group 0002, explicit VR little endian) and says how the data
 * set after it is encoded, by its transfer syntax (which DCMTK reads it in, dicom_scan.h). */
static int read_meta(struct scan *c, bool *implicit, bool *big)
{
    char *ts = c->s.transfer_syntax;
    while (c->at + 8 <= c->n && u16(c, c->at, false) == 0x0002) {
        uint32_t tag = 0x00020000u | u16(c, c->at + 2, false);
        if (!vr_in(c->b + c->at + 4, VRS))
            return fail(c, SF_EFORMAT, "not a readable DICOM object: a meta header element without a known VR", tag);
        bool lv = vr_in(c->b + c->at + 4, LONG_VRS);
        size_t head = lv ? 12 : 8;
        if (c->at + head > c->n)
            return fail(c, SF_EFORMAT, "not a readable DICOM object: the part ends inside a meta header element", tag);
        size_t len = lv ? u32(c, c->at + 8, false) : u16(c, c->at + 6, false);
        if (len > c->n - c->at - head)
            return fail(c, SF_EFORMAT, "not a readable DICOM object: an element is longer than the part", tag);
        if (tag == 0x00020010 && len < sizeof c->s.transfer_syntax) {
            memcpy(ts, c->b + c->at + head, len);
            ts[len] = 0;
            for (size_t k = len; k > 0 && (ts[k - 1] == ' ' || ts[k - 1] == 0); k--)
                ts[k - 1] = 0;
        }
        c->s.n_elements++;
        c->at += head + len;
    }
    if (!ts[0])
        return fail(c, SF_EFORMAT, "not a readable DICOM object: a meta header without its TransferSyntaxUID", 0x00020010);
    if (!strcmp(ts, "1.2.840.10008.1.2")) {
        *implicit = true, *big = false;
    } else if (!strcmp(ts, "1.2.840.10008.1.2.2")) {
        *implicit = false, *big = true;
    } else if (!strcmp(ts, "1.2.840.10008.1.2.1.99") || !strcmp(ts, "1.2.840.10008.1.2.4.95")) {
        return sf_fail(c->err, SF_EINVAL, c->pointer, "a deflated data set (%s) is not read: send it uncompressed", ts);
    } else if (!strncmp(ts, "1.2.840.10008.1.2.", 18)) {
        *implicit = false, *big = false; /* explicit VR little endian, the pixel data perhaps encapsulated */
    } else {
        return sf_fail(c->err, SF_EINVAL, c->pointer, "transfer syntax %s is not a standard one: send the object in "
                       "explicit or implicit VR little endian", ts);
    }
    return 0;
}

/* One item tag (FFFE,xxxx) inside a sequence, an item or a fragment list. */
static int read_item_tag(struct scan *c, struct frame *f, uint32_t tag, uint32_t len)
{
    c->at += 8;
    switch (tag) {
    case 0xfffee000u: /* an item */
        if (f->kind == F_SEQ) {
            if (len != UNDEFINED && len > f->end - c->at)
                return fault(c, "an item is longer than its sequence", tag);
            return push(c, F_ITEM, len, f->implicit, f->big, false, false, tag);
        }
        if (f->kind == F_FRAGS) {
            if (len == UNDEFINED || len > f->end - c->at)
                return fault(c, "a pixel data fragment is longer than the part", tag);
            c->at += len;
            return 0;
        }
        return fault(c, "an item outside a sequence", tag);
    case 0xfffee00du: /* the end of an item */
        if (f->kind != F_ITEM)
            return fault(c, "an item delimiter outside an item", tag);
        if (f->undefined)
            c->top--;
        return 0;
    case 0xfffee0ddu: /* the end of a sequence */
        if (f->kind != F_SEQ && f->kind != F_FRAGS)
            return fault(c, "a sequence delimiter outside a sequence", tag);
        if (f->undefined) {
            c->top--;
            c->depth--;
        }
        return 0;
    default:
        return fault(c, "an unknown item tag", tag);
    }
}

/* One data element of f (a data set or an item): its tag checked for order and creators, then
 * stepped over, or into when it is a sequence or encapsulated pixel data. */
static int read_element(struct scan *c, struct frame *f, uint32_t tag)
{
    size_t head = 8;
    uint32_t len;
    bool seq, frags = false, inner_implicit = f->implicit, inner_big = f->big, tentative = false;
    if (f->implicit) {
        /* the header within its item, as the explicit VR one below (one straddling an item's end
         * was read past it, its length then checked against a negative rest) */
        if (c->at + head > f->end)
            return fault(c, "the part ends inside an element", tag);
        len = u32(c, c->at + 4, f->big);
        seq = len == UNDEFINED && tag != 0x7fe00010u; /* undefined: a sequence (pixel data: fragments) */
        frags = len == UNDEFINED && !seq;
        /* DCMTK's dictionary says which defined-length elements are sequences; without it, a value
         * that starts with an item is taken for one. A private one (odd group: no dictionary knows
         * it) is stepped over whole if it is not; a public one is read as a sequence, faults and
         * all, as DCMTK reads it (ContourSequence and the like are SQ in its dictionary: stepping
         * over a broken one passed it, and DCMTK then allocated the 3.7 GB an element inside
         * declared; fuzz_instance) */
        if (len != UNDEFINED && len >= 8 && tag != 0x7fe00010u && c->at + 16 <= f->end &&
            u32(c, c->at + 8, f->big) == (f->big ? 0xfffee000u : 0xe000fffeu))
            seq = true, tentative = tag >> 16 & 1;
        /* blanking: the first walk found it was not one */
        if (tentative && c->next_not_seq < c->n_not_seq && c->not_seq[c->next_not_seq] == c->at + 8)
            seq = tentative = false, c->next_not_seq++;
    } else {
        const unsigned char *vr = c->b + c->at + 4;
        if (!vr_in(vr, VRS))
            return fault(c, "an element without a known VR", tag);
        bool lv = vr_in(vr, LONG_VRS);
        head = lv ? 12 : 8;
        if (c->at + head > f->end)
            return fault(c, "the part ends inside an element", tag);
        len = lv ? u32(c, c->at + 8, f->big) : u16(c, c->at + 6, f->big);
        seq = vr[0] == 'S' && vr[1] == 'Q';
        if (vr[0] == 'U' && vr[1] == 'N' && len == UNDEFINED) /* read as an implicit VR sequence (PS3.5 6.2.2) */
            seq = inner_implicit = true, inner_big = false;
        frags = !seq && len == UNDEFINED;
    }
    if (f->max_tag && tag < f->max_tag && ++c->s.n_disorder > DICOM_MAX_DISORDER) {
        char what[96];
        snprintf(what, sizeof what, "more than %d elements out of ascending tag order (PS3.5 7.1)", DICOM_MAX_DISORDER);
        return fail(c, SF_EFORMAT, what, tag);
    }
    if (tag > f->max_tag)
        f->max_tag = tag;
    if ((tag >> 16 & 1) && (tag & 0xffff) >= 0x10 && (tag & 0xffff) <= 0xff && ++f->n_creators > DICOM_MAX_CREATORS) {
        char what[96];
        snprintf(what, sizeof what, "more than %d private creators in one data set or item", DICOM_MAX_CREATORS);
        return fail(c, SF_ELIMIT, what, tag);
    }
    size_t start = c->at;
    c->at += head;
    if (len != UNDEFINED && len > f->end - c->at) {
        c->at = start;
        return fault(c, "an element is longer than the part", tag);
    }
    bool listed = c->w && identifying(tag);
    if (seq || frags) {
        int rc = push(c, frags ? F_FRAGS : F_SEQ, len, inner_implicit, inner_big, tentative, listed, tag);
        if (rc)
            c->at = start;
        return rc;
    }
    if (c->w && (f->blank || listed))
        blank(c, c->at, len, fill_for(tag, f->implicit ? NULL : c->b + start + 4));
    c->at += len;
    return 0;
}

/* The pass over c->b's c->n bytes (c's other fields as the caller set them). */
static int walk(struct scan *c)
{
    size_t len = c->n;
    bool implicit = false, big = false;
    int rc = 0;
    /* "DICM" only after the preamble: DCMTK reads one at 0 as an element (4944,4D43), and so must this */
    if (len >= 132 && !memcmp(c->b + 128, "DICM", 4))
        c->at = 132;
    if (c->at || (len >= 8 && u16(c, 0, false) == 0x0002 && vr_in(c->b + 4, VRS)))
        rc = read_meta(c, &implicit, &big);
    else
        guess_syntax(c, 0, &implicit, &big);
    c->s.implicit = implicit, c->s.big_endian = big;
    c->st[0] = (struct frame){.kind = F_DATASET, .end = len, .implicit = implicit, .big = big};
    while (!rc && c->at + 8 <= len) {
        struct frame *f = &c->st[c->top];
        if (f->kind != F_DATASET && !f->undefined && c->at >= f->end) {
            if (f->kind == F_SEQ || f->kind == F_FRAGS)
                c->depth--;
            c->top--; /* a defined length ends */
            continue;
        }
        if (c->at + 8 > f->end) {
            rc = fault(c, "the part ends inside an element", 0);
            continue;
        }
        if (++c->s.n_elements > DICOM_MAX_ELEMENTS) {
            rc = sf_fail(c->err, SF_ELIMIT, c->pointer, "more than %d elements, items and fragments", DICOM_MAX_ELEMENTS);
            break;
        }
        uint32_t tag = (uint32_t)u16(c, c->at, f->big) << 16 | u16(c, c->at + 2, f->big);
        if (tag >> 16 == 0xfffe)
            rc = read_item_tag(c, f, tag, u32(c, c->at + 4, f->big));
        else if (f->kind == F_DATASET || f->kind == F_ITEM)
            rc = read_element(c, f, tag);
        else
            rc = fault(c, f->kind == F_SEQ ? "an element where a sequence has items" : "an element among pixel data fragments", tag);
    }
    /* what is left is under 8 bytes, or delimiters never came: DCMTK says what it makes of that */
    return rc;
}

int dicom_scan(const void *data, size_t len, const char *pointer, struct dicom_scan_stats *stats, struct sf_err *err)
{
    struct scan c = {.b = data, .n = len, .pointer = pointer ? pointer : "", .err = err};
    int rc = walk(&c);
    if (stats)
        *stats = c.s;
    return rc;
}

int dicom_blank_identity(void *data, size_t len, const char *pointer, size_t *n_blanked, struct sf_err *err)
{
    struct scan c = {.b = data, .n = len, .pointer = pointer ? pointer : "", .err = err, .note_not_seq = true};
    int rc = walk(&c);
    struct scan wr = {.b = data, .w = data, .n = len, .pointer = c.pointer, .err = err, .not_seq = c.not_seq,
                      .n_not_seq = c.n_not_seq};
    if (!rc)
        rc = walk(&wr);
    if (n_blanked)
        *n_blanked = wr.n_blanked;
    free(c.not_seq);
    return rc;
}

bool dicom_sniff(const void *data, size_t len)
{
    const unsigned char *b = data;
    if (len >= 132 && !memcmp(b + 128, "DICM", 4))
        return true;
    if (len < 8 || b[1] != 0 || (b[0] != 2 && b[0] != 8))
        return false;
    bool explicit_vr = b[4] >= 'A' && b[4] <= 'Z' && b[5] >= 'A' && b[5] <= 'Z';
    uint32_t implicit_len = (uint32_t)b[4] | (uint32_t)b[5] << 8 | (uint32_t)b[6] << 16 | (uint32_t)b[7] << 24;
    return explicit_vr || implicit_len <= len - 8;
}
