/* test_volume_io.c - the readers of POST /isosurface's volumes: raw with its query, NRRD (raw,
 * gzip, big-endian, unaligned data), MetaImage; every kind of bad input with its pointer. */
#include "../../api/volume_io.h"

#include <zlib.h>

#include "../unit.h"

static int rd(const char *body, size_t len, const char *format, const char *options, struct volume *v,
              struct sf_err *err)
{
    memset(err, 0, sizeof *err);
    return volume_read(body, len, format, options, v, err);
}

/* An error with that code and pointer. */
static bool refused(const char *body, size_t len, const char *format, const char *options, int code, const char *ptr)
{
    struct volume v;
    struct sf_err err;
    int rc = rd(body, len, format, options, &v, &err);
    if (!rc)
        volume_free(&v);
    if (rc != code || strncmp(err.pointer, ptr, strlen(ptr)))
        fprintf(stderr, "  %s | %s: rc %d pointer \"%s\" (%s), expected %d \"%s\"\n", format, options, rc, err.pointer,
                err.message, code, ptr);
    return rc == code && !strncmp(err.pointer, ptr, strlen(ptr));
}

static int16_t samples[4 * 3 * 2] = {-5, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 300};

TEST(raw_samples)
{
    struct volume v;
    struct sf_err err;
    CHECK(rd((const char *)samples, sizeof samples, "raw", "iso=10.5&dims=4,3,2&type=int16&spacing=0.5,0.5,2&origin=1,2,3",
             &v, &err) == 0);
    CHECK(v.g.nx == 4 && v.g.ny == 3 && v.g.nz == 2 && v.g.type == ISO_I16 && v.g.samples == samples);
    CHECK(v.g.spacing[2] == 2 && v.g.origin[1] == 2 && v.iso == 10.5 && v.closed);
    volume_free(&v);
    CHECK(rd((const char *)samples, sizeof samples, "", "iso=1&dims=4,3,2&type=int16&closed=false", &v, &err) == 0);
    CHECK(!v.closed && v.g.spacing[0] == 1);
    volume_free(&v);
    const char *b = (const char *)samples;
    size_t n = sizeof samples;
    CHECK(refused(b, n - 2, "raw", "iso=1&dims=4,3,2&type=int16", SF_EINVAL, "?dims"));
    CHECK(refused(b, n, "raw", "dims=4,3,2&type=int16", SF_EINVAL, "?iso"));
    CHECK(refused(b, n, "raw", "iso=nan&dims=4,3,2&type=int16", SF_EINVAL, "?iso"));
    CHECK(refused(b, n, "raw", "iso=1&type=int16", SF_EINVAL, "?dims"));
    CHECK(refused(b, n, "raw", "iso=1&dims=4,3&type=int16", SF_EINVAL, "?dims"));
    CHECK(refused(b, n, "raw", "iso=1&dims=4,3,1&type=int16", SF_EINVAL, "?dims"));
    CHECK(refused(b, n, "raw", "iso=1&dims=4,3,2&type=int64", SF_EINVAL, "?type"));
    CHECK(refused(b, n, "raw", "iso=1&dims=4,3,2", SF_EINVAL, "?type"));
    CHECK(refused(b, n, "raw", "iso=1&dims=100000,100000,100000&type=uint8", SF_ELIMIT, "?dims"));
    CHECK(refused(b, n, "raw", "iso=1&dims=4,3,2&type=int16&spacing=nan,1,1", SF_EINVAL, "?spacing"));
    CHECK(refused(b, n, "raw", "iso=1&dims=4,3,2&type=int16&spacing=0,1,1", SF_EINVAL, "?spacing"));
    CHECK(refused(b, n, "raw", "iso=1&dims=4,3,2&type=int16&closed=maybe", SF_EINVAL, "?closed"));
    CHECK(refused(b, n, "raw", "iso=1&dims=4,3,2&type=int16&levels=9", SF_EINVAL, "?levels"));
    /* sniffed: samples whose first byte is '{' are raw samples, not an FRep object */
    uint8_t brace[8] = {'{', 200, 3, '"', 9, 1, 0, 7};
    CHECK(rd((const char *)brace, sizeof brace, "", "iso=5&dims=2,2,2&type=uint8", &v, &err) == 0);
    CHECK(v.g.nx == 2 && !strcmp(v.source, "isosurface"));
    volume_free(&v);
    CHECK(!strcmp(volume_format_of(" {\"sphere\": 1}", 15, "", ""), "frep") && !strcmp(volume_format_of("{}", 2, "", ""), "frep"));
    CHECK(!strcmp(volume_format_of((const char *)brace, sizeof brace, "", ""), "raw"));
    /* a DICOM file: "DICM" after the preamble, or an explicit VR element of group 0008 first; bytes
     * that would be one only in implicit VR stay raw samples (application/dicom says otherwise) */
    char part10[140] = {0}, bare[12] = {8, 0, 0x16, 0, 'U', 'I', 2, 0, '1', 0, 0, 0}, implicit[12] = {8, 0, 0x16, 0, 2, 0, 0, 0};
    memcpy(part10 + 128, "DICM", 4);
    CHECK(!strcmp(volume_format_of(part10, sizeof part10, "", ""), "dicom"));
    CHECK(!strcmp(volume_format_of(part10, sizeof part10, "raw", ""), "dicom"));
    CHECK(!strcmp(volume_format_of(part10, sizeof part10, "raw", "dims=2,2,35"), "raw"));
    CHECK(!strcmp(volume_format_of(bare, sizeof bare, "", ""), "dicom"));
    CHECK(!strcmp(volume_format_of(implicit, sizeof implicit, "", ""), "raw"));
    CHECK(!strcmp(volume_format_of("--b\r\n", 5, "raw", ""), "dicom"));
    CHECK(refused((const char *)brace, sizeof brace, "raw", "iso=5&dims=2,2,2&type=uint8&segment=1", SF_EINVAL, "?segment"));
    uint8_t dashes[8] = {'-', '-', 3, 200, 9, '\n', 0, 7}; /* (a multipart body's start, but for the bytes) */
    CHECK(rd((const char *)dashes, sizeof dashes, "", "iso=5&dims=2,2,2&type=uint8", &v, &err) == 0);
    CHECK(v.g.nx == 2);
    volume_free(&v);
    float f[8] = {0, 1, 2, 3, 4, 5, 6, 0};
    f[5] = NAN;
    CHECK(refused((const char *)f, sizeof f, "raw", "iso=1&dims=2,2,2&type=float32", SF_EINVAL, "?dims"));
}

/* header + samples in one buffer */
static char *with_header(const char *header, const void *data, size_t n, size_t *len)
{
    size_t h = strlen(header);
    char *b = malloc(h + n);
    memcpy(b, header, h);
    memcpy(b + h, data, n);
    *len = h + n;
    return b;
}

TEST(nrrd)
{
    struct volume v;
    struct sf_err err;
    size_t len;
    /* an odd header length: the samples are not aligned in the body */
    char *b = with_header("NRRD0004\n# x\ntype: int16\ndimension: 3\nsizes: 4 3 2\nspace directions: (0.5,0,0) (0,0.5,0) "
                          "(0,0,2)\nendian: little\nencoding: raw\nspace origin: (1,2,3)\n\n", samples, sizeof samples, &len);
    CHECK(rd(b, len, "nrrd", "iso=10", &v, &err) == 0);
    CHECK(v.g.nx == 4 && v.g.nz == 2 && v.g.spacing[0] == 0.5 && v.g.spacing[2] == 2 && v.g.origin[2] == 3);
    CHECK(memcmp(v.g.samples, samples, sizeof samples) == 0);
    volume_free(&v);
    CHECK(rd(b, len, "", "iso=10", &v, &err) == 0); /* sniffed */
    volume_free(&v);
    CHECK(refused(b, len - 1, "nrrd", "iso=10", SF_EINVAL, "data"));
    CHECK(refused(b, len, "nrrd", "iso=10&dims=4,3,2", SF_EINVAL, "?dims"));
    free(b);
    /* big-endian */
    int16_t be[24];
    for (int k = 0; k < 24; k++)
        be[k] = (int16_t)((uint16_t)samples[k] >> 8 | (uint16_t)samples[k] << 8);
    b = with_header("NRRD0004\ntype: short\ndimension: 3\nsizes: 4 3 2\nendian: big\nencoding: raw\n\n", be, sizeof be, &len);
    CHECK(rd(b, len, "nrrd", "iso=10", &v, &err) == 0);
    CHECK(v.g.samples && memcmp(v.g.samples, samples, sizeof samples) == 0);
    volume_free(&v);
    free(b);
    /* gzip */
    unsigned char z[256];
    z_stream zs = {0};
    deflateInit2(&zs, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY);
    zs.next_in = (unsigned char *)samples;
    zs.avail_in = sizeof samples;
    zs.next_out = z;
    zs.avail_out = sizeof z;
    deflate(&zs, Z_FINISH);
    size_t zn = sizeof z - zs.avail_out;
    deflateEnd(&zs);
    b = with_header("NRRD0005\ntype: int16\ndimension: 3\nsizes: 4 3 2\nspacings: 1 1 1\nencoding: gzip\n\n", z, zn, &len);
    CHECK(rd(b, len, "nrrd", "iso=10", &v, &err) == 0);
    CHECK(v.g.samples && memcmp(v.g.samples, samples, sizeof samples) == 0);
    volume_free(&v);
    CHECK(refused(b, len - 4, "nrrd", "iso=10", SF_EINVAL, "")); /* cut short */
    free(b);
    /* garbage and what is not read */
    static const struct {
        const char *header, *pointer;
        int code;
    } BAD[] = {
        {"NRRD0004\ntype: int64\ndimension: 3\nsizes: 4 3 2\n\n", "header line 2", SF_EINVAL},
        {"NRRD0004\ntype: int16\ndimension: 2\nsizes: 4 3\n\n", "header line 3", SF_EINVAL},
        {"NRRD0004\ntype: int16\ndimension: 3\nsizes: 4 3 x\n\n", "header line 4", SF_EINVAL},
        {"NRRD0004\ntype: int16\nsizes: 4 3 2\ndata file: ct.raw\n\n", "header line 4", SF_EINVAL},
        {"NRRD0004\ntype: int16\nsizes: 4 3 2\nspace directions: (1,1,0) (0,1,0) (0,0,1)\n\n", "header line 4", SF_EINVAL},
        {"NRRD0004\ntype: int16\nsizes: 4 3 2\nencoding: bzip2\n\n", "header line 4", SF_EINVAL},
        {"NRRD0004\ntype: int16\n\n", "header", SF_EINVAL},
        {"NRRD0004\ntype int16\n\n", "header", SF_EFORMAT},
        {"NRRD0004\ntype: int16\nsizes: 4 3 2\n", "header", SF_EFORMAT},
        {"NRRD0004\ntype: int16\nsizes: 99999 99999 99999\n\n", "header", SF_ELIMIT},
        {"NRRX", "header", SF_EFORMAT},
    };
    for (size_t k = 0; k < sizeof BAD / sizeof *BAD; k++) {
        b = with_header(BAD[k].header, samples, sizeof samples, &len);
        CHECK(refused(b, len, "nrrd", "iso=1", BAD[k].code, BAD[k].pointer));
        free(b);
    }
}

TEST(metaimage)
{
    struct volume v;
    struct sf_err err;
    size_t len;
    char *b = with_header("ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
                          "CompressedData = False\nOffset = 1 2 3\nElementSpacing = 0.5 0.5 2\nDimSize = 4 3 2\n"
                          "ElementType = MET_SHORT\nElementDataFile = LOCAL\n", samples, sizeof samples, &len);
    CHECK(rd(b, len, "mha", "iso=10", &v, &err) == 0);
    CHECK(v.g.nx == 4 && v.g.ny == 3 && v.g.spacing[2] == 2 && v.g.origin[0] == 1);
    CHECK(memcmp(v.g.samples, samples, sizeof samples) == 0);
    volume_free(&v);
    CHECK(rd(b, len, "", "iso=10", &v, &err) == 0);
    volume_free(&v);
    free(b);
    b = with_header("ObjectType = Image\nNDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\nElementDataFile = ct.raw\n",
                    samples, sizeof samples, &len);
    CHECK(refused(b, len, "mha", "iso=10", SF_EINVAL, "header line 5"));
    free(b);
    b = with_header("ObjectType = Image\nNDims = 3\nDimSize = 4 3 2\nElementType = MET_DOUBLE\nElementDataFile = LOCAL\n",
                    samples, sizeof samples, &len);
    CHECK(refused(b, len, "mha", "iso=10", SF_EINVAL, "header line 4"));
    free(b);
}

/* Every origin, spacing and iso in ranges.h's ranges, else a 422 (SF_EINVAL) naming the option or
 * the header line (issue 48: an origin of 1e300 answered 500 "out of memory", 1e-300 mm spacings
 * and an origin 1e9 mm out stored meshes of volume 0). */
TEST(numbers_in_range)
{
    const char *b = (const char *)samples;
    size_t n = sizeof samples;
    static const struct {
        const char *options, *pointer;
    } RAW[] = {
        {"iso=-1e308", "?iso"},
        {"iso=1e31", "?iso"},
        {"iso=40000", "?iso"},                                /* past int16 */
        {"iso=1&origin=1e300,0,0", "?origin"},
        {"iso=1&origin=0,-1e9,0", "?origin"},
        {"iso=1&origin=0,0,1000001", "?origin"},
        {"iso=1&spacing=1e-300,1,1", "?spacing"},
        {"iso=1&spacing=1,1,0.0009", "?spacing"},
        {"iso=1&spacing=1,20000,1", "?spacing"},
        {"iso=1&spacing=1e4,1,1&origin=980000,0,0", "?spacing"}, /* the far corner 1 010 000 mm out */
        {"iso=1&spacing=0.001,1,1&origin=1e6,0,0", "?spacing"},   /* cells float32 cannot hold apart there */
    };
    for (size_t k = 0; k < sizeof RAW / sizeof *RAW; k++) {
        char q[160];
        snprintf(q, sizeof q, "dims=4,3,2&type=int16&%s", RAW[k].options);
        CHECK(refused(b, n, "raw", q, SF_EINVAL, RAW[k].pointer));
    }
    struct volume v;
    struct sf_err err;
    CHECK(rd(b, n, "raw", "iso=32767&dims=4,3,2&type=int16&spacing=1e-3,1e4,1&origin=900,-1e6,1000", &v, &err) == 0);
    volume_free(&v);
    float f[8] = {0, 1, 2, 3, 4, 5, 6, 7};
    CHECK(rd((const char *)f, sizeof f, "raw", "iso=-1e30&dims=2,2,2&type=float32", &v, &err) == 0);
    volume_free(&v);
    static const struct {
        const char *header, *pointer;
    } HDR[] = {
        {"NRRD0004\ntype: int16\ndimension: 3\nsizes: 4 3 2\nspace origin: (1e300,0,0)\nencoding: raw\n\n",
         "header line 5"},
        {"NRRD0004\ntype: int16\ndimension: 3\nsizes: 4 3 2\nspacings: 1 1e-300 1\nencoding: raw\n\n", "header line 5"},
        {"NRRD0004\ntype: int16\nsizes: 4 3 2\nspace directions: (1e5,0,0) (0,1,0) (0,0,1)\n\n", "header line 4"},
        {"ObjectType = Image\nNDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\nOffset = 1e300 0 0\n"
         "ElementDataFile = LOCAL\n", "header line 5"},
        {"ObjectType = Image\nNDims = 3\nDimSize = 4 3 2\nElementSpacing = 1e-300 1 1\nElementType = MET_SHORT\n"
         "ElementDataFile = LOCAL\n", "header line 4"},
    };
    for (size_t k = 0; k < sizeof HDR / sizeof *HDR; k++) {
        size_t len;
        char *h = with_header(HDR[k].header, samples, sizeof samples, &len);
        CHECK(refused(h, len, "", "iso=1", SF_EINVAL, HDR[k].pointer));
        free(h);
    }
    static const struct {
        const char *body, *pointer;
    } FREP[] = {
        {"{\"bounds\": [[-2e6, 0, 0], [1, 1, 1]], \"cell\": 0.5, \"frep\": {\"sphere\": {\"center\": [0, 0, 0], "
         "\"radius\": 1}}}", "/bounds/0"},
        {"{\"bounds\": [[0, 0, 0], [0.01, 0.01, 0.01]], \"cell\": 0.0001, \"frep\": {\"sphere\": {\"center\": [0, 0, 0], "
         "\"radius\": 1}}}", "/cell"},
    };
    for (size_t k = 0; k < sizeof FREP / sizeof *FREP; k++)
        CHECK(refused(FREP[k].body, strlen(FREP[k].body), "frep", "", SF_EINVAL, FREP[k].pointer));
}

/* The shared CT crop as an attached NRRD reads the same samples as its raw file. */
TEST(shared_ct_as_nrrd)
{
    size_t n;
    char *raw = unit_data("volumes", "ct_head_crop64_int16.raw", &n);
    CHECK(raw != NULL);
    if (!raw)
        return;
    size_t len;
    char *b = with_header("NRRD0004\ntype: int16\ndimension: 3\nsizes: 64 64 64\nspace directions: (0.9570312,0,0) "
                          "(0,0.9570312,0) (0,0,1.5)\nendian: little\nencoding: raw\n\n", raw, n, &len);
    struct volume v;
    struct sf_err err;
    CHECK(rd(b, len, "nrrd", "iso=226.5", &v, &err) == 0);
    CHECK(v.g.nx == 64 && memcmp(v.g.samples, raw, n) == 0);
    volume_free(&v);
    free(b);
    free(raw);
}

/* A slice whose element declares more bytes than the part holds is refused before DCMTK
 * allocates them (as fuzz_volume found: 2.3 GB asked for by a 20-byte part), at any depth. */
TEST(dicom_lengths_over_the_part)
{
    static const char head[] = "--b\r\nContent-Disposition: form-data; name=\"slice\"\r\n\r\n", tail[] = "\r\n--b--\r\n";
    /* implicit VR: (0008,0005) length 0x7fffffff; explicit: an OB of 2^31; a sequence's item */
    static const unsigned char parts[][24] = {
        {0x08, 0, 0x05, 0, 0xff, 0xff, 0xff, 0x7f, 'I', 'S', 'O'},
        {0x08, 0, 0x05, 0, 'C', 'S', 0x02, 0, 'A', 'B', 0xe0, 0x7f, 0x10, 0, 'O', 'B', 0, 0, 0, 0, 0, 0x80},
        {0x08, 0, 0x15, 0x11, 0xff, 0xff, 0xff, 0xff, 0xfe, 0xff, 0, 0xe0, 0xff, 0xff, 0xff, 0xff, 0x08, 0, 0x50, 0x11,
         0, 0, 0, 0x40},
    };
    static const size_t lens[] = {11, 22, 24};
    for (int k = 0; k < 3; k++) {
        char body[512];
        size_t n = 0;
        for (int twice = 0; twice < 2; twice++) { /* a series is two slices at least */
            memcpy(body + n, head, sizeof head - 1), n += sizeof head - 1;
            memcpy(body + n, "DICM", 4), n += 4;
            memcpy(body + n, parts[k], lens[k]), n += lens[k];
            if (!twice)
                memcpy(body + n, "\r\n", 2), n += 2;
        }
        memcpy(body + n, tail, sizeof tail - 1), n += sizeof tail - 1;
        CHECK(refused(body, n, "dicom", "iso=1", SF_EFORMAT, "/parts/0"));
        struct volume v;
        struct sf_err err;
        CHECK(rd(body, n, "dicom", "iso=1", &v, &err) && strstr(err.message, "longer than the part"));
    }
}

int main(void)
{
    RUN(raw_samples);
    RUN(dicom_lengths_over_the_part);
    RUN(nrrd);
    RUN(metaimage);
    RUN(numbers_in_range);
    RUN(shared_ct_as_nrrd);
    UNIT_END();
}
