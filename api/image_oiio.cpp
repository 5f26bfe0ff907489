// image_oiio.cpp - the only C++ in surfd's image path: frame buffers to PNG/EXR/TIFF bytes with
// OpenImageIO writing into memory (Filesystem::IOVecOutput). PNG is RGB, zlib level 2, no row
// filter: measured on the 1024² teapot, libpng's adaptive filter search took 40 ms of a 50 ms
// encode for 15 % smaller files; without it encoding is 11 ms, 7.3 ms at level 3 since the
// render's bands convert to 8-bit sRGB on its own threads (srgb8_only; tests/bench/RESULTS.md),
// and 6.7 ms at level 2 (114 KB against 106 KB). Level 1 (6.7 ms, 136 KB), zlib's run-length
// strategy (6.5 ms, 202 KB) and no compression at all (8.4 ms, 3 MB) are no faster: some 6 ms
// is the format's own work over the 3 MB of rows (their checksum and copies), whatever deflate does.
#include "image.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <vector>

using namespace OIIO;

static int write(const char *ext, ImageSpec &spec, const void *pixels, unsigned char **out, size_t *out_len,
                 struct sf_err *err)
{
    std::vector<unsigned char> bytes;
    Filesystem::IOVecOutput proxy(bytes);
    auto o = ImageOutput::create(std::string("mem") + ext, &proxy);
    if (!o)
        return sf_fail(err, SF_EBACKEND, "", "OpenImageIO has no %s writer", ext);
    if (!o->open(std::string("mem") + ext, spec) || !o->write_image(spec.format, pixels) || !o->close())
        return sf_fail(err, SF_EBACKEND, "", "OpenImageIO: %s", o->geterror().c_str());
    *out = (unsigned char *)std::malloc(bytes.size() ? bytes.size() : 1);
    if (!*out)
        return sf_fail(err, SF_ENOMEM, "", "out of memory for the image");
    std::memcpy(*out, bytes.data(), bytes.size());
    *out_len = bytes.size();
    return 0;
}

extern "C" void image_oiio_init(void)
{
    for (const char *ext : {"mem.png", "mem.exr", "mem.tif"})
        ImageOutput::create(ext); // the first create() loads the plugin catalogue
}

extern "C" int image_oiio_encode(const struct frame_image *img, enum image_format fmt, unsigned char **out,
                                 size_t *out_len, struct sf_err *err)
{
    *out = nullptr;
    *out_len = 0;
    const size_t n = (size_t)img->width * img->height;
    try {
        if (fmt == IMG_PNG) {
            // RGB: the background is part of the picture, so alpha would be 255 everywhere
            // (EXR carries the real coverage in A)
            // the render fills the 8-bit picture in its bands (scene.srgb8_only)
            if (!img->srgb8)
                return sf_fail(err, SF_EINVAL, "", "the frame holds no 8-bit picture: render it with srgb8_only");
            ImageSpec spec(img->width, img->height, 3, TypeDesc::UINT8);
            spec.attribute("png:compressionLevel", 2);
            spec.attribute("png:filter", 8 /* PNG_FILTER_NONE */);
            spec.attribute("oiio:ColorSpace", "sRGB");
            return write(".png", spec, img->srgb8, out, out_len, err);
        }
        if (!img->rgba)
            return sf_fail(err, SF_EINVAL, "", "the frame holds only an 8-bit picture: PNG alone can be written");
        if (fmt == IMG_TIFF) {
            std::vector<unsigned short> px(n * 4);
            for (size_t k = 0; k < 4 * n; k++)
                px[k] = (unsigned short)std::lround(std::fmin(std::fmax(img->rgba[k], 0.0f), 1.0f) * 65535.0f);
            ImageSpec spec(img->width, img->height, 4, TypeDesc::UINT16);
            spec.attribute("oiio:ColorSpace", "linear");
            spec.attribute("compression", "zip");
            return write(".tif", spec, px.data(), out, out_len, err);
        }
        // EXR: R G B A Z, then the AOVs asked for, interleaved float32
        std::vector<std::string> names = {"R", "G", "B", "A", "Z"};
        if (img->normal)
            names.insert(names.end(), {"N.x", "N.y", "N.z"});
        if (img->uv)
            names.insert(names.end(), {"u", "v"});
        if (img->id)
            names.push_back("id");
        const size_t nc = names.size();
        std::vector<float> px(n * nc);
        for (size_t k = 0; k < n; k++) {
            float *p = &px[k * nc];
            std::memcpy(p, &img->rgba[4 * k], 4 * sizeof(float));
            p[4] = img->depth[k];
            size_t c = 5;
            if (img->normal)
                std::memcpy(p + c, &img->normal[3 * k], 3 * sizeof(float)), c += 3;
            if (img->uv)
                std::memcpy(p + c, &img->uv[2 * k], 2 * sizeof(float)), c += 2;
            if (img->id)
                p[c] = img->id[k];
        }
        ImageSpec spec(img->width, img->height, (int)nc, TypeDesc::FLOAT);
        spec.channelnames = names;
        spec.alpha_channel = 3;
        spec.z_channel = 4;
        spec.attribute("compression", "zip");
        return write(".exr", spec, px.data(), out, out_len, err);
    } catch (const std::exception &e) {
        return sf_fail(err, SF_EBACKEND, "", "OpenImageIO: %s", e.what());
    }
}
