// C interface to OpenImageIO's writer and reader (see oiio_shim.h). Every entry point catches every C++
// exception: unwinding into Rust is undefined behaviour.

#include "oiio_shim.h"

#include <OpenImageIO/imageio.h>

#include <cctype>
#include <cstring>
#include <exception>
#include <initializer_list>
#include <memory>
#include <string>

namespace {

// Copies `text` into the caller's buffer, always NUL-terminated, truncated if needed.
void set_message(char *msg, size_t msg_len, const std::string &text) noexcept {
    if (msg == nullptr || msg_len == 0) {
        return;
    }
    size_t n = text.size() < msg_len - 1 ? text.size() : msg_len - 1;
    std::memcpy(msg, text.data(), n);
    msg[n] = '\0';
}

// Writes `a` followed by `b` without allocating, so it is safe inside a catch handler.
void set_message_raw(char *msg, size_t msg_len, const char *a, const char *b) noexcept {
    if (msg == nullptr || msg_len == 0) {
        return;
    }
    size_t n = 0;
    for (const char *s : {a, b}) {
        for (; s != nullptr && *s != '\0' && n + 1 < msg_len; ++s) {
            msg[n++] = *s;
        }
    }
    msg[n] = '\0';
}

int fail(char *msg, size_t msg_len, int code, const std::string &text) noexcept {
    try {
        set_message(msg, msg_len, text.empty() ? std::string("unknown OpenImageIO error") : text);
    } catch (...) {
    }
    return code;
}

std::string global_error() {
    std::string e = OIIO::geterror();
    return e;
}

int write_image(const char *path, int width, int height, int channels, int data_type, const void *data,
                int pixel_type, char *msg, size_t msg_len) {
    if (path == nullptr || data == nullptr) {
        return fail(msg, msg_len, PLX_ERR_ARGUMENT, "null path or pixel buffer");
    }
    if (width <= 0 || height <= 0 || channels <= 0) {
        return fail(msg, msg_len, PLX_ERR_ARGUMENT,
                    "invalid image size " + std::to_string(width) + "x" + std::to_string(height) + "x" +
                        std::to_string(channels));
    }
    OIIO::TypeDesc in_type;
    switch (data_type) {
    case PLX_DATA_FLOAT: in_type = OIIO::TypeDesc::FLOAT; break;
    case PLX_DATA_UINT8: in_type = OIIO::TypeDesc::UINT8; break;
    default: return fail(msg, msg_len, PLX_ERR_ARGUMENT, "unknown data type " + std::to_string(data_type));
    }
    OIIO::TypeDesc file_type;
    switch (pixel_type) {
    case PLX_PIXEL_FLOAT: file_type = OIIO::TypeDesc::FLOAT; break;
    case PLX_PIXEL_HALF: file_type = OIIO::TypeDesc::HALF; break;
    case PLX_PIXEL_UINT8: file_type = OIIO::TypeDesc::UINT8; break;
    default: return fail(msg, msg_len, PLX_ERR_ARGUMENT, "unknown pixel type " + std::to_string(pixel_type));
    }

    auto out = OIIO::ImageOutput::create(path);
    if (!out) {
        return fail(msg, msg_len, PLX_ERR_FORMAT, global_error());
    }
    // libjpeg's default error handler, which OpenImageIO 2.4's JPEG writer keeps, calls exit() on
    // an image larger than its limit: refuse such sizes here instead of losing the process.
    const int jpeg_max_dimension = 65500;
    if (std::string(out->format_name()) == "jpeg" && (width > jpeg_max_dimension || height > jpeg_max_dimension)) {
        return fail(msg, msg_len, PLX_ERR_ARGUMENT,
                    "JPEG images can be at most " + std::to_string(jpeg_max_dimension) + " pixels wide and high, not " +
                        std::to_string(width) + "x" + std::to_string(height));
    }
    OIIO::ImageSpec spec(width, height, channels, file_type);
    // 8-bit data has been tone mapped and encoded with the sRGB OETF; float data is scene-linear.
    spec.attribute("oiio:ColorSpace", data_type == PLX_DATA_UINT8 ? "sRGB" : "Linear");
    spec.attribute("Software", "plexus");
    if (!out->open(path, spec)) {
        return fail(msg, msg_len, PLX_ERR_OPEN, out->geterror());
    }
    if (!out->write_image(in_type, data)) {
        std::string e = out->geterror();
        out->close();
        return fail(msg, msg_len, PLX_ERR_WRITE, e);
    }
    if (!out->close()) {
        return fail(msg, msg_len, PLX_ERR_CLOSE, out->geterror());
    }
    return PLX_OK;
}

int can_write(const char *filename, char *msg, size_t msg_len) {
    if (filename == nullptr) {
        return fail(msg, msg_len, PLX_ERR_ARGUMENT, "null file name");
    }
    // create() only looks the writer up by extension; it neither opens nor creates the file.
    auto out = OIIO::ImageOutput::create(filename);
    if (!out) {
        return fail(msg, msg_len, PLX_ERR_FORMAT, global_error());
    }
    return PLX_OK;
}

// Opens `path` for reading with its colour channels as the file stores them. Without the hint,
// OpenImageIO multiplies the colours of a file with unassociated alpha (PNG, TGA, some TIFFs) by
// their alpha on read, so a texel of alpha 0 reads as black whatever its colour; plexus ignores a
// texture's alpha (opacity is its own parameter) and Mitsuba 3 reads such colours as stored. EXR
// stores associated alpha, which the hint leaves alone.
std::unique_ptr<OIIO::ImageInput> open_unassociated(const char *path) {
    OIIO::ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);
    return OIIO::ImageInput::open(path, &config);
}

int read_info(const char *path, plx_image_info *info, char *msg, size_t msg_len) {
    if (path == nullptr || info == nullptr) {
        return fail(msg, msg_len, PLX_ERR_ARGUMENT, "null path or info");
    }
    auto in = open_unassociated(path);
    if (!in) {
        return fail(msg, msg_len, PLX_ERR_OPEN, global_error());
    }
    const OIIO::ImageSpec &spec = in->spec();
    info->width = spec.width;
    info->height = spec.height;
    info->channels = spec.nchannels;
    info->is_float = spec.format.is_floating_point() ? 1 : 0;
    std::string cs = spec.get_string_attribute("oiio:ColorSpace");
    for (auto &c : cs) {
        c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    }
    info->color_space = cs == "srgb" ? 1 : (cs == "linear" || cs == "scene_linear" || cs == "lin_srgb") ? 2 : 0;
    bool uint8 = spec.format == OIIO::TypeDesc::UINT8;
    for (const auto &f : spec.channelformats) {
        uint8 = uint8 && f == OIIO::TypeDesc::UINT8;
    }
    info->is_uint8 = uint8 ? 1 : 0;
    in->close();
    return PLX_OK;
}

// Channels [0, read_channels) of the first subimage of `path` in `format` into `data`, after
// checking that its size is still the one the caller allocated for.
int read_pixels(const char *path, int width, int height, int channels, int read_channels, OIIO::TypeDesc format,
                void *data, char *msg, size_t msg_len) {
    if (path == nullptr || data == nullptr || width <= 0 || height <= 0 || channels <= 0 || read_channels <= 0 ||
        read_channels > channels) {
        return fail(msg, msg_len, PLX_ERR_ARGUMENT, "null path or buffer, or a non-positive size");
    }
    auto in = open_unassociated(path);
    if (!in) {
        return fail(msg, msg_len, PLX_ERR_OPEN, global_error());
    }
    const OIIO::ImageSpec &spec = in->spec();
    if (spec.width != width || spec.height != height || spec.nchannels != channels) {
        in->close();
        return fail(msg, msg_len, PLX_ERR_ARGUMENT, "the image changed size while being read");
    }
    if (!in->read_image(0, 0, 0, read_channels, format, data)) {
        std::string e = in->geterror();
        in->close();
        return fail(msg, msg_len, PLX_ERR_WRITE, e);
    }
    in->close();
    return PLX_OK;
}

int read_image(const char *path, int width, int height, int channels, float *data, char *msg, size_t msg_len) {
    return read_pixels(path, width, height, channels, channels, OIIO::TypeDesc::FLOAT, data, msg, msg_len);
}

int read_image_uint8(const char *path, int width, int height, int channels, int read_channels, unsigned char *data,
                     float *levels, char *msg, size_t msg_len) {
    if (levels == nullptr) {
        return fail(msg, msg_len, PLX_ERR_ARGUMENT, "null levels");
    }
    unsigned char codes[256];
    for (int c = 0; c < 256; ++c) {
        codes[c] = static_cast<unsigned char>(c);
    }
    // The conversion read_image(FLOAT) applies to 8-bit pixels.
    if (!OIIO::convert_pixel_values(OIIO::TypeDesc::UINT8, codes, OIIO::TypeDesc::FLOAT, levels, 256)) {
        return fail(msg, msg_len, PLX_ERR_ARGUMENT, "cannot convert 8-bit levels to float");
    }
    return read_pixels(path, width, height, channels, read_channels, OIIO::TypeDesc::UINT8, data, msg, msg_len);
}

// Runs `body` (one of the functions above), turning any C++ exception into PLX_ERR_EXCEPTION
// with its message: no exception crosses into Rust.
template <typename Body>
int guarded(char *msg, size_t msg_len, Body &&body) noexcept {
    try {
        return body();
    } catch (const std::exception &e) {
        set_message_raw(msg, msg_len, "C++ exception: ", e.what());
        return PLX_ERR_EXCEPTION;
    } catch (...) {
        set_message_raw(msg, msg_len, "unknown C++ exception", nullptr);
        return PLX_ERR_EXCEPTION;
    }
}

}  // namespace

extern "C" int plx_oiio_write_image(const char *path, int width, int height, int channels, int data_type,
                                    const void *data, int pixel_type, char *msg, size_t msg_len) noexcept {
    return guarded(msg, msg_len, [&] {
        return write_image(path, width, height, channels, data_type, data, pixel_type, msg, msg_len);
    });
}

extern "C" int plx_oiio_can_write(const char *filename, char *msg, size_t msg_len) noexcept {
    return guarded(msg, msg_len, [&] { return can_write(filename, msg, msg_len); });
}

extern "C" int plx_oiio_read_info(const char *path, plx_image_info *info, char *msg, size_t msg_len) noexcept {
    return guarded(msg, msg_len, [&] { return read_info(path, info, msg, msg_len); });
}

extern "C" int plx_oiio_read_image_uint8(const char *path, int width, int height, int channels, int read_channels,
                                         unsigned char *data, float *levels, char *msg, size_t msg_len) noexcept {
    return guarded(msg, msg_len, [&] {
        return read_image_uint8(path, width, height, channels, read_channels, data, levels, msg, msg_len);
    });
}

extern "C" int plx_oiio_read_image(const char *path, int width, int height, int channels, float *data, char *msg,
                                   size_t msg_len) noexcept {
    return guarded(msg, msg_len, [&] { return read_image(path, width, height, channels, data, msg, msg_len); });
}
