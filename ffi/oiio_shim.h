/* A small C interface to OpenImageIO's image writer and reader, for Rust.
 *
 * Every function returns PLX_OK (0) or one of the error codes below and, on error, writes a
 * NUL-terminated message into `msg` (truncated to `msg_len` bytes, `msg` may be NULL when
 * `msg_len` is 0). No C++ exception ever leaves these functions. */
#pragma once

#include <stddef.h>

#ifdef __cplusplus
#define PLX_NOEXCEPT noexcept
extern "C" {
#else
#define PLX_NOEXCEPT
#endif

/* Type of the caller's pixel buffer. */
enum plx_data_type { PLX_DATA_FLOAT = 0, PLX_DATA_UINT8 = 1 };

/* Pixel type stored in the file (the writer converts; formats that cannot store it get the
 * closest type they support, as OpenImageIO decides). */
enum plx_pixel_type { PLX_PIXEL_FLOAT = 0, PLX_PIXEL_HALF = 1, PLX_PIXEL_UINT8 = 2 };

enum plx_status {
    PLX_OK = 0,
    PLX_ERR_ARGUMENT = 1,  /* null pointer, non-positive size, unknown enum value */
    PLX_ERR_FORMAT = 2,    /* no OpenImageIO writer for this file name's extension */
    PLX_ERR_OPEN = 3,      /* the writer could not create/open the file */
    PLX_ERR_WRITE = 4,     /* writing the pixels failed */
    PLX_ERR_CLOSE = 5,     /* flushing/closing the file failed */
    PLX_ERR_EXCEPTION = 6  /* a C++ exception was caught */
};

/* Writes a `width` x `height` image with `channels` interleaved channels, row 0 at the top, to
 * `path`; the format is chosen by the extension of `path`. `data` holds
 * width*height*channels values of `data_type`. `pixel_type` is what the file stores. 8-bit data is
 * tagged as sRGB, float data as linear. */
int plx_oiio_write_image(const char *path, int width, int height, int channels, int data_type,
                         const void *data, int pixel_type, char *msg, size_t msg_len) PLX_NOEXCEPT;

/* PLX_OK if OpenImageIO has a writer for the extension of `filename` (nothing is opened or
 * created), PLX_ERR_FORMAT otherwise. */
int plx_oiio_can_write(const char *filename, char *msg, size_t msg_len) PLX_NOEXCEPT;

/* What `plx_oiio_read_info` reports about an image file. */
struct plx_image_info {
    int width;
    int height;
    int channels;
    /* 1 if the file stores floating-point (half, float, double) pixels, 0 for integers. */
    int is_float;
    /* 1 if the file says its pixels are sRGB-encoded ("oiio:ColorSpace" sRGB), 2 if it says
     * linear, 0 if it says neither. */
    int color_space;
    /* 1 if every channel is stored as 8-bit unsigned integers (JPEG, most PNGs): then
     * plx_oiio_read_image_uint8 reads the codes themselves. */
    int is_uint8;
};

/* Opens `path` and reports the size, channel count and encoding of its first subimage.
 * Errors: PLX_ERR_FORMAT (no reader, or not an image), PLX_ERR_OPEN. */
int plx_oiio_read_info(const char *path, struct plx_image_info *info, char *msg, size_t msg_len) PLX_NOEXCEPT;

/* Reads the first subimage of `path` as 32-bit floats, row 0 at the top, `channels` interleaved
 * channels per pixel, into `data` (width*height*channels floats, `width`/`height` as
 * `plx_oiio_read_info` reported them; a size that no longer matches is PLX_ERR_ARGUMENT). Integer
 * formats are normalised to [0, 1]; no colour conversion is made. Errors: PLX_ERR_OPEN,
 * PLX_ERR_WRITE (reading the pixels failed). */
int plx_oiio_read_image(const char *path, int width, int height, int channels, float *data, char *msg,
                        size_t msg_len) PLX_NOEXCEPT;

/* Reads channels [0, read_channels) (1 <= read_channels <= channels) of the first subimage of an
 * 8-bit file (`is_uint8`) as their byte codes, interleaved, row 0 at the top, into `data`
 * (width*height*read_channels bytes), and into `levels` (256 floats) the float OpenImageIO makes
 * of each code: plx_oiio_read_image's value of a channel is levels[its code], without the float
 * buffer four times the size. Errors as plx_oiio_read_image's. */
int plx_oiio_read_image_uint8(const char *path, int width, int height, int channels, int read_channels,
                              unsigned char *data, float *levels, char *msg, size_t msg_len) PLX_NOEXCEPT;

#ifdef __cplusplus
}
#endif
