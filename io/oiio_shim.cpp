// io/oiio_shim.cpp — OpenImageIO behind a C interface. Every entry point catches every exception.
#include "io/oiio_shim.h"

#include <OpenImageIO/imageio.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <memory>
#include <string>
#include <vector>

extern "C" {
#include "base/error.h"
}

using namespace OIIO;

static int fail(char *errbuf, size_t errlen, int code, const std::string &msg)
{
    if (errbuf && errlen)
        std::snprintf(errbuf, errlen, "%s", msg.c_str());
    return code;
}

extern "C" int sci_oiio_read(const char *path, float **data, int *w, int *h, int *nframes, int *bits, char *errbuf,
                             size_t errlen)
{
    *data = nullptr;
    try {
        auto in = ImageInput::open(path);
        if (!in) {
            std::string e = OIIO::geterror();
            return fail(errbuf, errlen, SCI_EFORMAT, std::string(path) + ": cannot read image (" + e + ")");
        }
        std::vector<float> all;
        int W = 0, H = 0, n = 0, b = 0;
        for (int sub = 0; in->seek_subimage(sub, 0); sub++) {
            const ImageSpec &spec = in->spec();
            if (sub == 0) {
                W = spec.width;
                H = spec.height;
                b = (int)spec.format.size() * 8;
            } else if (spec.width != W || spec.height != H) {
                break; /* a thumbnail or a different-size page is not a frame of the stack */
            }
            if (W < 1 || H < 1 || spec.depth > 1)
                return fail(errbuf, errlen, SCI_EFORMAT, std::string(path) + ": unsupported image geometry");
            const int nc = spec.nchannels;
            std::vector<float> pix((size_t)W * H * nc);
            /* Read as float *without* OIIO's normalisation: ask for the native type and convert ourselves. */
            TypeDesc fmt = spec.format;
            if (fmt.basetype == TypeDesc::HALF || fmt.basetype == TypeDesc::DOUBLE)
                fmt = TypeDesc::FLOAT; /* float types are converted without normalisation */
            std::vector<unsigned char> raw((size_t)W * H * nc * fmt.size());
            if (!in->read_image(sub, 0, 0, nc, fmt, raw.data()))
                return fail(errbuf, errlen, SCI_EFORMAT, std::string(path) + ": " + in->geterror());
            for (size_t i = 0; i < pix.size(); i++) {
                const unsigned char *p = raw.data() + i * fmt.size();
                double v;
                switch (fmt.basetype) {
                case TypeDesc::UINT8: v = *(const uint8_t *)p; break;
                case TypeDesc::INT8: v = *(const int8_t *)p; break;
                case TypeDesc::UINT16: v = *(const uint16_t *)p; break;
                case TypeDesc::INT16: v = *(const int16_t *)p; break;
                case TypeDesc::UINT32: v = *(const uint32_t *)p; break;
                case TypeDesc::INT32: v = *(const int32_t *)p; break;
                case TypeDesc::FLOAT: v = *(const float *)p; break;
                case TypeDesc::DOUBLE: v = *(const double *)p; break;
                default:
                    return fail(errbuf, errlen, SCI_EFORMAT, std::string(path) + ": unsupported pixel type " +
                                                                 std::string(fmt.c_str()));
                }
                pix[i] = (float)v;
            }
            size_t base = all.size();
            all.resize(base + (size_t)W * H);
            for (size_t i = 0; i < (size_t)W * H; i++) {
                if (nc >= 3)
                    all[base + i] = 0.2126f * pix[i * nc] + 0.7152f * pix[i * nc + 1] + 0.0722f * pix[i * nc + 2];
                else
                    all[base + i] = pix[i * nc]; /* grey, or grey + alpha */
            }
            n++;
        }
        in->close();
        if (n == 0)
            return fail(errbuf, errlen, SCI_EFORMAT, std::string(path) + ": no image data");
        float *out = (float *)std::malloc(all.size() * sizeof(float));
        if (!out)
            return fail(errbuf, errlen, -ENOMEM, std::string(path) + ": out of memory");
        std::memcpy(out, all.data(), all.size() * sizeof(float));
        *data = out;
        *w = W;
        *h = H;
        *nframes = n;
        if (bits)
            *bits = b;
        return 0;
    } catch (const std::exception &e) {
        return fail(errbuf, errlen, -EIO, std::string(path) + ": " + e.what());
    } catch (...) {
        return fail(errbuf, errlen, -EIO, std::string(path) + ": unknown C++ exception in OpenImageIO");
    }
}

extern "C" int sci_oiio_probe(const char *path, int *w, int *h, char *errbuf, size_t errlen)
{
    try {
        auto in = ImageInput::open(path);
        if (!in) {
            std::string e = OIIO::geterror();
            return fail(errbuf, errlen, SCI_EFORMAT, std::string(path) + ": cannot read image (" + e + ")");
        }
        *w = in->spec().width;
        *h = in->spec().height;
        in->close();
        return 0;
    } catch (const std::exception &e) {
        return fail(errbuf, errlen, -EIO, std::string(path) + ": " + e.what());
    } catch (...) {
        return fail(errbuf, errlen, -EIO, std::string(path) + ": unknown C++ exception in OpenImageIO");
    }
}

extern "C" int sci_oiio_write(const char *path, const float *data, int w, int h, int channels, int pixel_type,
                              const char *description, int uncompressed, char *errbuf, size_t errlen)
{
    try {
        TypeDesc t = pixel_type == 0 ? TypeDesc::UINT8
                     : pixel_type == 1 ? TypeDesc::UINT16
                     : pixel_type == 2 ? TypeDesc::HALF
                                       : TypeDesc::FLOAT;
        auto out = ImageOutput::create(path);
        if (!out)
            return fail(errbuf, errlen, SCI_EFORMAT,
                        std::string(path) + ": no image writer for this extension (" + OIIO::geterror() + ")");
        if (channels != 1 && channels != 3)
            return fail(errbuf, errlen, -EINVAL, std::string(path) + ": " + std::to_string(channels) +
                                                     " channels (1 or 3 are written)");
        ImageSpec spec(w, h, channels, t);
        std::string p(path);
        auto ends = [&](const char *s) {
            size_t l = std::strlen(s);
            return p.size() >= l && p.compare(p.size() - l, l, s) == 0;
        };
        /* deflate level 1 everywhere: level 4-6 (the defaults) costs 2-4 times the CPU for 5-15 % fewer bytes on
         * 256×256 frames, and reconstructed float frames hardly compress at any level */
        if (ends(".tif") || ends(".tiff")) {
            spec.attribute("compression", uncompressed ? "none" : "zip");
            spec.attribute("tiff:zipquality", 1);
        } else if (ends(".exr")) {
            spec.attribute("compression", uncompressed ? "none" : "zip:1");
        } else if (ends(".png")) {
            spec.attribute("png:compressionLevel", 1);
        }
        if (description && *description)
            spec.attribute("ImageDescription", description);
        if (!out->open(path, spec))
            return fail(errbuf, errlen, -EIO, p + ": " + out->geterror());
        /* Hand integer files their native type: OpenImageIO would otherwise map float [0, 1] to the full integer
         * range, and our values are already counts. */
        std::vector<uint8_t> u8;
        std::vector<uint16_t> u16;
        const void *pixels = data;
        TypeDesc given = TypeDesc::FLOAT;
        const size_t count = (size_t)w * h * channels;
        if (pixel_type == 0) {
            u8.resize(count);
            for (size_t i = 0; i < count; i++)
                u8[i] = (uint8_t)data[i];
            pixels = u8.data();
            given = TypeDesc::UINT8;
        } else if (pixel_type == 1) {
            u16.resize(count);
            for (size_t i = 0; i < count; i++)
                u16[i] = (uint16_t)data[i];
            pixels = u16.data();
            given = TypeDesc::UINT16;
        }
        if (!out->write_image(given, pixels)) {
            std::string e = out->geterror();
            out->close();
            return fail(errbuf, errlen, -EIO, p + ": " + e);
        }
        if (!out->close())
            return fail(errbuf, errlen, -EIO, p + ": " + out->geterror());
        return 0;
    } catch (const std::exception &e) {
        return fail(errbuf, errlen, -EIO, std::string(path) + ": " + e.what());
    } catch (...) {
        return fail(errbuf, errlen, -EIO, std::string(path) + ": unknown C++ exception in OpenImageIO");
    }
}

extern "C" void sci_oiio_exr_threads(int threads)
{
    try {
        OIIO::attribute("exr_threads", threads);
    } catch (...) {
        /* an attribute cannot fail in a way we could act on: the pool keeps its size */
    }
}
