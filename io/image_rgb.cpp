// io/image_rgb.cpp — the one OpenImageIO call colour output needs (3-channel images), in the style of
// io/oiio_shim.cpp: extern "C", every C++ exception caught. Used only by io/image.c (sci_image_write_rgb).
#include <OpenImageIO/imageio.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "base/error.h"

using namespace OIIO;

static int rgb_fail(char *errbuf, size_t errlen, int code, const std::string &msg)
{
    std::snprintf(errbuf, errlen, "%s", msg.c_str());
    return code;
}

/* Write one w×h RGB image from interleaved float samples already in the type's range (integer types rounded by
 * the caller). pixel_type as sci_oiio_write: 0 uint8, 1 uint16, 2 half, 3 float. */
extern "C" int sci_oiio_write_rgb(const char *path, const float *rgb, int w, int h, int pixel_type, char *errbuf,
                                  size_t errlen)
{
    try {
        TypeDesc t = pixel_type == 0 ? TypeDesc::UINT8
                     : pixel_type == 1 ? TypeDesc::UINT16
                     : pixel_type == 2 ? TypeDesc::HALF
                                       : TypeDesc::FLOAT;
        auto out = ImageOutput::create(path);
        if (!out)
            return rgb_fail(errbuf, errlen, SCI_EFORMAT, std::string(path) + ": no image writer for this extension");
        ImageSpec spec(w, h, 3, t);
        std::string p(path);
        if (p.size() > 4 && p.compare(p.size() - 4, 4, ".exr") == 0)
            spec.attribute("compression", "zip");
        if (!out->open(path, spec))
            return rgb_fail(errbuf, errlen, -EIO, p + ": " + out->geterror());
        const size_t count = (size_t)w * h * 3;
        std::vector<uint8_t> u8;
        std::vector<uint16_t> u16;
        const void *pixels = rgb;
        TypeDesc given = TypeDesc::FLOAT;
        if (pixel_type == 0) {
            u8.resize(count);
            for (size_t i = 0; i < count; i++)
                u8[i] = (uint8_t)rgb[i];
            pixels = u8.data();
            given = TypeDesc::UINT8;
        } else if (pixel_type == 1) {
            u16.resize(count);
            for (size_t i = 0; i < count; i++)
                u16[i] = (uint16_t)rgb[i];
            pixels = u16.data();
            given = TypeDesc::UINT16;
        }
        if (!out->write_image(given, pixels)) {
            std::string e = out->geterror();
            out->close();
            return rgb_fail(errbuf, errlen, -EIO, p + ": " + e);
        }
        if (!out->close())
            return rgb_fail(errbuf, errlen, -EIO, p + ": " + out->geterror());
        return 0;
    } catch (const std::exception &e) {
        return rgb_fail(errbuf, errlen, -EIO, std::string(path) + ": " + e.what());
    } catch (...) {
        return rgb_fail(errbuf, errlen, -EIO, std::string(path) + ": unknown error");
    }
}
