// ImageIO: rendered images as file bytes, in memory (the caller writes them, e.g. atomically with
// writeFileAtomic, or to standard output).
//
//   OpenEXR  linear RGB, half or float, ZIP-compressed scanlines: the image as computed, for
//            compositing and for reading values back (decodeExr).
//   PNG      8-bit sRGB preview, tone mapped (ToneMap below), written by a small encoder of our
//            own over zlib: signature, IHDR, sRGB + gAMA, one IDAT, IEND.
//
// Tone mapping (PNG only): scale = 2^exposureStops, times, with autoExposure, key / Y_p where Y_p
// is the percentile-p luminance (Rec. 709: 0.2126 R + 0.7152 G + 0.0722 B) of the pixels that show
// the scene (Image::coverage > 0; every pixel if the coverage is unknown). Defaults: the 90th
// percentile maps to 0.8, so the brightest tenth (lights, hot spots) may clip while the lit
// surfaces keep their gradations. If that luminance is not positive (a black image) the auto
// factor is 1. Then each channel is clamped to [0, 1] (NaN as 0) and encoded with the sRGB
// transfer function (IEC 61966-2-1), rounded to 8 bits.
#pragma once

#include "vdbrad/render/Renderer.h"

#include <string>

namespace vdbrad {

enum class ExrPixel { Half, Float };

struct ToneMap
{
    double exposureStops = 0.0;   ///< extra exposure, in stops (factor 2^stops), finite
    bool autoExposure = true;     ///< scale so that the percentile luminance maps to key
    double percentile = 0.9;      ///< in [0, 1]
    double key = 0.8;             ///< linear value (before the sRGB curve), > 0
};

/// @brief The bytes of an OpenEXR file holding @a image: RGB channels of type @a pixel,
/// ZIP-compressed scanlines, data window (0, 0) - (width - 1, height - 1), top row first.
/// Half precision keeps 11 significant bits (relative rounding error <= 2^-11) up to 65504.
/// @throw openvdb::ValueError if the image is empty or its pixel count is not width x height
std::string encodeExr(const Image& image, ExrPixel pixel = ExrPixel::Half);

/// @brief Read an OpenEXR file held in memory: R, G and B channels (missing ones read as 0; a
/// luminance-only Y file is read as grey), any pixel type, converted to float. The coverage is
/// left empty.
/// @throw openvdb::IoError if the bytes are not a readable OpenEXR image or it has no R, G, B or Y
Image decodeExr(const std::string& bytes);

/// @brief The bytes of an 8-bit RGB PNG of @a image, tone mapped as the file comment says.
/// @throw openvdb::ValueError if the image is empty or inconsistent, or @a toneMap is invalid
std::string encodePng(const Image& image, const ToneMap& toneMap = ToneMap());

/// The factor the tone map applies to linear values of @a image (before clamping and sRGB).
double toneMapScale(const Image& image, const ToneMap& toneMap = ToneMap());

/// The sRGB transfer function (IEC 61966-2-1) of a linear value in [0, 1].
double srgbEncode(double linear);

} // namespace vdbrad
