/* test_dicom_scan.c - the structure pass before DCMTK (api/dicom_scan.c): objects built here byte
 * by byte in each encoding (explicit and implicit VR little endian, explicit big endian, with and
 * without the meta header), each cap at its value and one past it, and the shared data's real
 * RT Structure Sets and series, which must all pass. */
#include "../../api/dicom_scan.h"

#include <stdint.h>

#include "../unit.h"

/* ---- a growable byte buffer and the element writers ------------------------------------------ */

struct buf {
    unsigned char *b;
    size_t n, cap;
    bool big; /* tags and lengths big endian (the meta header is written little endian always) */
};

static void put(struct buf *o, const void *p, size_t n)
{
    if (o->n + n > o->cap) {
        o->cap = (o->n + n) * 2 + 64;
        o->b = realloc(o->b, o->cap);
    }
    memcpy(o->b + o->n, p, n);
    o->n += n;
}

static void put16(struct buf *o, unsigned v)
{
    unsigned char b[2] = {o->big ? v >> 8 : v & 0xff, o->big ? v & 0xff : v >> 8};
    put(o, b, 2);
}

static void put32(struct buf *o, uint32_t v)
{
    put16(o, o->big ? v >> 16 : v & 0xffff);
    put16(o, o->big ? v & 0xffff : v >> 16);
}

#define UNDEF 0xffffffffu

/* An explicit VR element's head (the value is the caller's). */
static void ehead(struct buf *o, unsigned g, unsigned e, const char *vr, uint32_t len)
{
    static const char LONG[] = "OBODOFOLOVOWSQSVUCUNURUTUV";
    const char *at = strstr(LONG, vr);
    while (at && (at - LONG) % 2) /* a pair, not the end of one and the start of the next */
        at = strstr(at + 1, vr);
    put16(o, g), put16(o, e), put(o, vr, 2);
    if (at) {
        put16(o, 0), put32(o, len);
    } else {
        put16(o, len);
    }
}

static void eel(struct buf *o, unsigned g, unsigned e, const char *vr, const char *val)
{
    size_t n = strlen(val);
    ehead(o, g, e, vr, (uint32_t)(n + (n & 1)));
    put(o, val, n);
    if (n & 1)
        put(o, " ", 1);
}

/* An implicit VR element's head. */
static void ihead(struct buf *o, unsigned g, unsigned e, uint32_t len) { put16(o, g), put16(o, e), put32(o, len); }

static void item_tag(struct buf *o, unsigned e, uint32_t len) { put16(o, 0xfffe), put16(o, e), put32(o, len); }

/* Preamble, "DICM" and a meta header naming ts. */
static void meta(struct buf *o, const char *ts)
{
    bool big = o->big;
    o->big = false;
    unsigned char pre[128] = {0};
    put(o, pre, sizeof pre);
    put(o, "DICM", 4);
    size_t n = strlen(ts) + (strlen(ts) & 1);
    ehead(o, 2, 0, "UL", 4), put32(o, (uint32_t)(8 + n));
    ehead(o, 2, 0x10, "UI", (uint32_t)n);
    put(o, ts, strlen(ts));
    if (strlen(ts) & 1)
        put(o, "", 1);
    o->big = big;
}

#define EXPLICIT_LE "1.2.840.10008.1.2.1"
#define IMPLICIT_LE "1.2.840.10008.1.2"
#define EXPLICIT_BE "1.2.840.10008.1.2.2"

static int scan(const struct buf *o, struct dicom_scan_stats *st, struct sf_err *err)
{
    memset(err, 0, sizeof *err);
    return dicom_scan(o->b, o->n, "/parts/3", st, err);
}

/* depth sequences of undefined length, each in the (undefined) item of the one above, explicit */
static void nest_explicit(struct buf *o, int depth, bool defined_items)
{
    for (int k = 0; k < depth; k++) {
        ehead(o, 0x0008, 0x1115, "SQ", UNDEF);
        item_tag(o, 0xe000, defined_items && k == depth - 1 ? 0 : UNDEF);
    }
    for (int k = 0; k < depth; k++) {
        if (!(defined_items && k == 0))
            item_tag(o, 0xe00d, 0);
        item_tag(o, 0xe0dd, 0);
    }
}

/* ---- the tests -------------------------------------------------------------------------------- */

TEST(a_plain_object_in_each_encoding)
{
    struct dicom_scan_stats st;
    struct sf_err err;
    struct buf o = {0};
    meta(&o, EXPLICIT_LE);
    eel(&o, 0x0008, 0x0016, "UI", "1.2.840.10008.5.1.4.1.1.2");
    eel(&o, 0x0020, 0x0032, "DS", "0\\0\\0");
    ehead(&o, 0x7fe0, 0x0010, "OW", 8), put(&o, "\1\0\2\0\3\0\4\0", 8);
    CHECK(scan(&o, &st, &err) == 0 && st.n_elements == 2 + 3 && !st.implicit && !st.big_endian && st.max_depth == 0);
    o.n = 0; /* implicit, no meta header */
    ihead(&o, 0x0008, 0x0016, 4), put(&o, "1.2\0", 4);
    ihead(&o, 0x0020, 0x0032, 6), put(&o, "0\\0\\0 ", 6);
    CHECK(scan(&o, &st, &err) == 0 && st.implicit && st.n_elements == 2);
    o.n = 0; /* implicit, said by the meta header */
    meta(&o, IMPLICIT_LE);
    ihead(&o, 0x0008, 0x0016, 4), put(&o, "1.2\0", 4);
    CHECK(scan(&o, &st, &err) == 0 && st.implicit);
    o.n = 0; /* explicit big endian: its data set's tags and lengths */
    o.big = true;
    meta(&o, EXPLICIT_BE);
    eel(&o, 0x0008, 0x0016, "UI", "1.2");
    ehead(&o, 0x0008, 0x1115, "SQ", UNDEF), item_tag(&o, 0xe000, 12), eel(&o, 0x0008, 0x1150, "UI", "1.2");
    item_tag(&o, 0xe0dd, 0);
    eel(&o, 0x0020, 0x0032, "DS", "0\\0\\0");
    CHECK(scan(&o, &st, &err) == 0 && st.big_endian && st.max_depth == 1);
    o.n = 0; /* big endian without a meta header: guessed from the first tag */
    eel(&o, 0x0008, 0x0016, "UI", "1.2");
    eel(&o, 0x0020, 0x0032, "DS", "0\\0\\0");
    CHECK(scan(&o, &st, &err) == 0 && st.big_endian && !st.implicit);
    o.big = false;
    o.n = 0; /* a deflated data set is refused by name: the pass cannot see into it */
    meta(&o, "1.2.840.10008.1.2.1.99");
    put(&o, "\x78\x9c\0\0\0\0\0\0\0\0", 10);
    CHECK(scan(&o, &st, &err) == SF_EINVAL && strstr(err.message, "deflated") && !strcmp(err.pointer, "/parts/3"));
    free(o.b);
}

TEST(nesting_is_capped)
{
    struct dicom_scan_stats st;
    struct sf_err err;
    struct buf o = {0};
    meta(&o, EXPLICIT_LE);
    nest_explicit(&o, DICOM_MAX_DEPTH, false);
    CHECK(scan(&o, &st, &err) == 0 && st.max_depth == DICOM_MAX_DEPTH);
    o.n = 0;
    meta(&o, EXPLICIT_LE);
    nest_explicit(&o, DICOM_MAX_DEPTH + 1, false);
    CHECK(scan(&o, &st, &err) == SF_ELIMIT && strstr(err.message, "nested deeper") && !strcmp(err.pointer, "/parts/3"));
    o.n = 0; /* 10 000 deep, as the finding's part: refused at the cap, in no time */
    meta(&o, EXPLICIT_LE);
    nest_explicit(&o, 10000, false);
    CHECK(scan(&o, &st, &err) == SF_ELIMIT && st.max_depth == DICOM_MAX_DEPTH);
    o.n = 0; /* implicit VR, undefined lengths: sequences by their length alone */
    for (int k = 0; k <= DICOM_MAX_DEPTH; k++)
        ihead(&o, 0x0008, 0x1115, UNDEF), item_tag(&o, 0xe000, UNDEF);
    CHECK(scan(&o, &st, &err) == SF_ELIMIT);
    o.n = 0; /* implicit VR, defined lengths: sequences because their values start with an item */
    size_t lens[DICOM_MAX_DEPTH + 1];
    for (int k = 0; k <= DICOM_MAX_DEPTH; k++) {
        lens[k] = o.n;
        ihead(&o, 0x0008, 0x1115, 0), item_tag(&o, 0xe000, 0);
    }
    ihead(&o, 0x0008, 0x1150, 4), put(&o, "1.2\0", 4);
    for (int k = 0; k <= DICOM_MAX_DEPTH; k++) { /* fill in the lengths, inside out */
        uint32_t sq = (uint32_t)(o.n - lens[k] - 8), it = sq - 8;
        memcpy(o.b + lens[k] + 4, &sq, 4);
        memcpy(o.b + lens[k] + 12, &it, 4);
    }
    CHECK(scan(&o, &st, &err) == SF_ELIMIT);
    o.n = 0; /* explicit VR, UN of undefined length: an implicit VR sequence inside (PS3.5 6.2.2) */
    meta(&o, EXPLICIT_LE);
    ehead(&o, 0x0009, 0x1001, "UN", UNDEF);
    for (int k = 0; k < DICOM_MAX_DEPTH; k++)
        item_tag(&o, 0xe000, UNDEF), ihead(&o, 0x0009, 0x1001, UNDEF);
    CHECK(scan(&o, &st, &err) == SF_ELIMIT);
    free(o.b);
}

TEST(order_and_creators_are_capped)
{
    struct dicom_scan_stats st;
    struct sf_err err;
    struct buf o = {0};
    meta(&o, EXPLICIT_LE);
    eel(&o, 0x0020, 0x0032, "DS", "0\\0\\0");
    for (int k = 0; k < DICOM_MAX_DISORDER; k++) /* a few appended carelessly: read */
        eel(&o, 0x0008, (unsigned)(0x0100 + k), "LO", "x");
    CHECK(scan(&o, &st, &err) == 0 && st.n_disorder == DICOM_MAX_DISORDER);
    eel(&o, 0x0008, 0x0200, "LO", "x");
    CHECK(scan(&o, &st, &err) == SF_EFORMAT && strstr(err.message, "ascending") && strstr(err.message, "(0008,0200)"));
    o.n = 0; /* descending: refused at the 17th */
    meta(&o, EXPLICIT_LE);
    for (unsigned e = 0xffff; e > 0xff00; e--)
        ehead(&o, 0x0019, e, "LO", 0);
    CHECK(scan(&o, &st, &err) == SF_EFORMAT && st.n_disorder == DICOM_MAX_DISORDER + 1);
    o.n = 0; /* order is per data set: an item starts afresh */
    meta(&o, EXPLICIT_LE);
    eel(&o, 0x0020, 0x0032, "DS", "0\\0\\0");
    ehead(&o, 0x3006, 0x0039, "SQ", UNDEF);
    for (int k = 0; k < 100; k++) {
        item_tag(&o, 0xe000, UNDEF);
        eel(&o, 0x0008, 0x1150, "UI", "1.2");
        eel(&o, 0x3006, 0x0084, "IS", "1");
        item_tag(&o, 0xe00d, 0);
    }
    item_tag(&o, 0xe0dd, 0);
    CHECK(scan(&o, &st, &err) == 0 && st.n_disorder == 0 && st.max_depth == 1);
    o.n = 0; /* private creators */
    meta(&o, EXPLICIT_LE);
    for (int k = 0; k < DICOM_MAX_CREATORS; k++)
        eel(&o, 0x0009 + 2 * (k / 200), (unsigned)(0x10 + k % 200), "LO", "SURFD");
    CHECK(scan(&o, &st, &err) == 0);
    eel(&o, 0x0019, 0x10, "LO", "SURFD");
    CHECK(scan(&o, &st, &err) == SF_ELIMIT && strstr(err.message, "private creators"));
    free(o.b);
}

TEST(elements_are_capped)
{
    struct dicom_scan_stats st;
    struct sf_err err;
    struct buf o = {0};
    meta(&o, EXPLICIT_LE);
    size_t base = o.n;
    o.cap = base + 8 * (size_t)(DICOM_MAX_ELEMENTS + 1);
    o.b = realloc(o.b, o.cap);
    REQUIRE(o.b);
    for (unsigned long k = 0; k < DICOM_MAX_ELEMENTS - 2; k++) /* and the meta header's 2 */
        ehead(&o, 0x0009 + 2 * (unsigned)(k / 0xf000), 0x1000 + (unsigned)(k % 0xf000), "LO", 0);
    CHECK(scan(&o, &st, &err) == 0 && st.n_elements == DICOM_MAX_ELEMENTS);
    ehead(&o, 0x00ff, 0x1000, "LO", 0);
    CHECK(scan(&o, &st, &err) == SF_ELIMIT && strstr(err.message, "more than"));
    free(o.b);
}

TEST(lengths_and_structure)
{
    struct dicom_scan_stats st;
    struct sf_err err;
    struct buf o = {0};
    meta(&o, EXPLICIT_LE);
    ehead(&o, 0x7fe0, 0x0010, "OB", 0x8fffffff); /* 2.3 GB declared in a small part */
    put(&o, "abcd", 4);
    CHECK(scan(&o, &st, &err) == SF_EFORMAT && strstr(err.message, "longer"));
    o.n = 0; /* an item longer than its sequence */
    meta(&o, EXPLICIT_LE);
    ehead(&o, 0x0008, 0x1115, "SQ", 16), item_tag(&o, 0xe000, 100);
    eel(&o, 0x0008, 0x1150, "UI", "1.2");
    CHECK(scan(&o, &st, &err) == SF_EFORMAT);
    o.n = 0; /* an element where a sequence has items */
    meta(&o, EXPLICIT_LE);
    ehead(&o, 0x0008, 0x1115, "SQ", UNDEF), eel(&o, 0x0008, 0x1150, "UI", "1.2");
    CHECK(scan(&o, &st, &err) == SF_EFORMAT && strstr(err.message, "items"));
    o.n = 0; /* an unknown VR */
    meta(&o, EXPLICIT_LE);
    eel(&o, 0x0008, 0x0016, "UI", "1.2");
    eel(&o, 0x0008, 0x0018, "Q?", "1.2");
    CHECK(scan(&o, &st, &err) == SF_EFORMAT && strstr(err.message, "VR"));
    o.n = 0; /* encapsulated pixel data: an offset table and two fragments */
    meta(&o, EXPLICIT_LE);
    eel(&o, 0x0028, 0x0010, "US", "\4");
    ehead(&o, 0x7fe0, 0x0010, "OB", UNDEF);
    item_tag(&o, 0xe000, 0), item_tag(&o, 0xe000, 4), put(&o, "\xff\xd8\xff\xd9", 4);
    item_tag(&o, 0xe000, 2), put(&o, "ab", 2), item_tag(&o, 0xe0dd, 0);
    CHECK(scan(&o, &st, &err) == 0 && st.max_depth == 1);
    o.n -= 8 + 10; /* a fragment of undefined length */
    item_tag(&o, 0xe000, UNDEF), put(&o, "ab", 2);
    CHECK(scan(&o, &st, &err) == SF_EFORMAT && strstr(err.message, "fragment"));
    o.n = 0; /* implicit VR: a value that starts like an item but is not a sequence is stepped over */
    ihead(&o, 0x0009, 0x1001, 12), item_tag(&o, 0xe000, 99), put(&o, "\0\0\0\0", 4);
    ihead(&o, 0x0009, 0x1002, 4), put(&o, "abcd", 4);
    CHECK(scan(&o, &st, &err) == 0 && st.max_depth == 0 && st.n_elements == 2);
    /* ... and pixel data is never taken for one */
    o.n = 0;
    ihead(&o, 0x7fe0, 0x0010, 16), item_tag(&o, 0xe000, 8), ihead(&o, 0x0008, 0x0001, 0);
    CHECK(scan(&o, &st, &err) == 0 && st.max_depth == 0);
    o.n = 0; /* implicit VR: an item's last element whose header runs past the item's end, its length
              * huge (was passed: the rest after its header wrapped, and DCMTK allocated 3.7 GB) */
    ihead(&o, 0x3006, 0x0040, 8 + 4 + 8), item_tag(&o, 0xe000, 4), put16(&o, 0x2d5c), put16(&o, 0x3232);
    put32(&o, 0xe000fffe), ihead(&o, 0x3006, 0x0042, 0);
    CHECK(scan(&o, &st, &err) == SF_EFORMAT && strstr(err.message, "ends inside"));
    o.n = 0; /* an item outside a sequence */
    meta(&o, EXPLICIT_LE);
    item_tag(&o, 0xe000, UNDEF);
    CHECK(scan(&o, &st, &err) == SF_EFORMAT && strstr(err.message, "outside"));
    CHECK(dicom_scan(NULL, 0, NULL, &st, &err) == 0 && st.n_elements == 0); /* nothing: DCMTK says what it is */
    free(o.b);
}

/* blanking, in implicit VR where defined-length sequences are known only by their first item:
 * a name inside a real one is blanked; a private value that only starts like one is blanked
 * whole (identifying: private) and counts as one element; a public one is a sequence in DCMTK's
 * dictionary, read as one and refused when it is broken */
TEST(blanking_sees_sequences_as_dcmtk_does)
{
    struct dicom_scan_stats st;
    struct sf_err err;
    struct buf o = {0};
    ihead(&o, 0x0008, 0x1115, 8 + 8 + 6), item_tag(&o, 0xe000, 8 + 6); /* a sequence: an item, a name */
    ihead(&o, 0x0010, 0x0010, 6), put(&o, "Doe^J ", 6);
    size_t priv = o.n; /* starts like one: an item of 14 bytes, then a name, then 4 bytes past the item */
    ihead(&o, 0x0009, 0x1001, 8 + 8 + 6 + 4), item_tag(&o, 0xe000, 8 + 6); /* the same, private */
    ihead(&o, 0x0008, 0x0001, 6), put(&o, "Poe^L ", 6), put(&o, "\1\2\3\4", 4);
    ihead(&o, 0x0009, 0x1002, 0);
    unsigned char *before = malloc(o.n);
    REQUIRE(before);
    memcpy(before, o.b, o.n);
    CHECK(scan(&o, &st, &err) == 0 && st.n_elements == 1 + 2 + 1 + 1 && st.max_depth == 1);
    size_t n = 0;
    CHECK(dicom_blank_identity(o.b, o.n, "", &n, &err) == 0 && n == 3); /* the name, (0009,1001), (0009,1002) */
    static const unsigned char zeros[26];
    CHECK(!memcmp(o.b + 24, "      ", 6) && !memcmp(o.b + priv + 8, zeros, 26));
    CHECK(!memcmp(o.b, before, 24)); /* the heads */
    struct dicom_scan_stats st2;
    CHECK(scan(&o, &st2, &err) == 0 && st2.n_elements == st.n_elements && st2.max_depth == st.max_depth);
    o.n = 0; /* a public one (ReferencedImageSequence) whose item holds an element longer than the item:
              * refused, as DCMTK reads a sequence there; the private one is stepped over */
    ihead(&o, 0x0008, 0x1140, 8 + 8 + 6), item_tag(&o, 0xe000, 8 + 6);
    ihead(&o, 0x0010, 0x0010, 100), put(&o, "Roe^K ", 6);
    CHECK(scan(&o, &st, &err) == SF_EFORMAT && strstr(err.message, "longer"));
    o.b[0] = 0x09, o.b[1] = 0x00; /* (0009,1140) */
    CHECK(scan(&o, &st, &err) == 0 && st.n_elements == 1);
    free(before);
    free(o.b);
}

/* the people PS3.15 E.1-1 names that multi-frame objects carry: a study's physicians and
 * operators, a Segmentation's Content Creator, an RT object's reviewer; each blanked, each
 * inside an identification sequence too, and the modality beside them kept */
TEST(blanking_names_the_people)
{
    static const unsigned tags[][2] = {
        {0x0008, 0x0090}, {0x0008, 0x009c}, {0x0008, 0x1048}, {0x0008, 0x1050}, {0x0008, 0x1070},
        {0x0010, 0x2297}, {0x0040, 0xa075}, {0x0070, 0x0084}, {0x300e, 0x0008},
    };
    struct buf o = {0};
    ihead(&o, 0x0008, 0x0060, 4), put(&o, "SEG ", 4);
    for (size_t k = 0; k < sizeof tags / sizeof *tags; k++)
        ihead(&o, tags[k][0], tags[k][1], 6), put(&o, "Roe^K ", 6);
    ihead(&o, 0x0070, 0x0086, 8 + 8 + 6), item_tag(&o, 0xe000, 8 + 6); /* Content Creator's Identification Code */
    ihead(&o, 0x0008, 0x0100, 6), put(&o, "4711  ", 6);
    size_t n = 0;
    struct sf_err err;
    CHECK(dicom_blank_identity(o.b, o.n, "", &n, &err) == 0 && n == sizeof tags / sizeof *tags + 1);
    CHECK(!memcmp(o.b + 8, "SEG ", 4));
    for (size_t k = 0; k < sizeof tags / sizeof *tags; k++)
        CHECK(!memcmp(o.b + 12 + 14 * k + 8, "      ", 6));
    CHECK(!memcmp(o.b + o.n - 6, "      ", 6));
    free(o.b);
}

/* every real object of the shared data passes, none nested past 4 */
TEST(real_objects_pass)
{
    static const char *const files[][2] = {
        {"contours", "dicompyler-core_example_rtss.dcm"},
        {"contours", "slicerrt_EclipseProstatePhantom_RS.dcm"},
        {"contours", "synthetic_torus_branching.rtstruct.dcm"},
        {"volumes", "dicom_ct_head_64x64x27/IM0001.dcm"},
        {"volumes", "dicom_pydicom_ct5n_16x16x5/2062.dcm"},
    };
    for (size_t k = 0; k < sizeof files / sizeof *files; k++) {
        size_t len;
        char *b = unit_data(files[k][0], files[k][1], &len);
        REQUIRE(b);
        struct dicom_scan_stats st;
        struct sf_err err = {0};
        int rc = dicom_scan(b, len, "", &st, &err);
        if (rc)
            fprintf(stderr, "  %s: %s\n", files[k][1], err.message);
        CHECK(rc == 0 && st.max_depth <= 4 && st.n_disorder == 0 && st.n_elements > 30);
        free(b);
    }
}

int main(void)
{
    RUN(a_plain_object_in_each_encoding);
    RUN(nesting_is_capped);
    RUN(order_and_creators_are_capped);
    RUN(elements_are_capped);
    RUN(lengths_and_structure);
    RUN(blanking_sees_sequences_as_dcmtk_does);
    RUN(blanking_names_the_people);
    RUN(real_objects_pass);
    UNIT_END();
}
