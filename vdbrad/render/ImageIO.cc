#include "vdbrad/render/ImageIO.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStdIO.h>
#include <half.h>

#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace vdbrad {

namespace {

void
checkImage(const Image& image)
{
    if (image.width < 1 || image.height < 1) {
        OPENVDB_THROW(openvdb::ValueError, "image is empty (" << image.width << " x "
            << image.height << ")");
    }
    if (image.pixels.size() != size_t(image.width) * size_t(image.height)) {
        OPENVDB_THROW(openvdb::ValueError, "image has " << image.pixels.size() << " pixels, not "
            << image.width << " x " << image.height);
    }
    if (!image.coverage.empty() && image.coverage.size() != image.pixels.size()) {
        OPENVDB_THROW(openvdb::ValueError, "image coverage has " << image.coverage.size()
            << " values for " << image.pixels.size() << " pixels");
    }
}

// PNG chunks: big-endian 32-bit length, type, data, CRC-32 of type and data.
void
putU32(std::string& out, uint32_t v)
{
    out.push_back(char((v >> 24) & 0xff));
    out.push_back(char((v >> 16) & 0xff));
    out.push_back(char((v >> 8) & 0xff));
    out.push_back(char(v & 0xff));
}

void
putChunk(std::string& out, const char type[4], const std::string& data)
{
    putU32(out, uint32_t(data.size()));
    const std::string typed = std::string(type, 4) + data;
    out += typed;
    const uLong crc = crc32(crc32(0L, Z_NULL, 0),
        reinterpret_cast<const Bytef*>(typed.data()), uInt(typed.size()));
    putU32(out, uint32_t(crc));
}

} // namespace

// ---- OpenEXR ---------------------------------------------------------------------------------

std::string
encodeExr(const Image& image, ExrPixel pixel)
{
    checkImage(image);
    const int W = image.width, H = image.height;
    const char* names[3] = {"R", "G", "B"};
    try {
        Imf::Header header(W, H);
        header.compression() = Imf::ZIP_COMPRESSION;
        const Imf::PixelType type = pixel == ExrPixel::Half ? Imf::HALF : Imf::FLOAT;
        for (const char* c : names) header.channels().insert(c, Imf::Channel(type));

        Imf::FrameBuffer fb;
        std::vector<half> halves;
        if (pixel == ExrPixel::Half) {
            // OpenEXR converts float slices to a half file itself, but converting here keeps
            // the rounding (round to nearest even, Imath's) explicit and documented.
            halves.resize(image.pixels.size() * 3);
            for (size_t i = 0; i < image.pixels.size(); ++i) {
                for (int c = 0; c < 3; ++c) halves[3 * i + size_t(c)] = half(image.pixels[i][c]);
            }
            for (int c = 0; c < 3; ++c) {
                fb.insert(names[c], Imf::Slice(Imf::HALF,
                    reinterpret_cast<char*>(&halves[size_t(c)]), 3 * sizeof(half),
                    3 * sizeof(half) * size_t(W)));
            }
        } else {
            // Vec3f is three packed floats: the slices read the image in place.
            char* base = const_cast<char*>(reinterpret_cast<const char*>(image.pixels.data()));
            for (int c = 0; c < 3; ++c) {
                fb.insert(names[c], Imf::Slice(Imf::FLOAT, base + size_t(c) * sizeof(float),
                    sizeof(openvdb::Vec3f), sizeof(openvdb::Vec3f) * size_t(W)));
            }
        }
        Imf::StdOSStream stream;
        {
            Imf::OutputFile file(stream, header);
            file.setFrameBuffer(fb);
            file.writePixels(H);
        }   // the destructor finishes the file (line offset table)
        return stream.str();
    } catch (const openvdb::Exception&) {
        throw;
    } catch (const std::exception& e) {
        OPENVDB_THROW(openvdb::IoError, "cannot encode OpenEXR image: " << e.what());
    }
}

Image
decodeExr(const std::string& bytes)
{
    try {
        Imf::StdISStream stream;
        stream.str(bytes);
        Imf::InputFile file(stream);
        const Imath::Box2i dw = file.header().dataWindow();
        const int64_t W = int64_t(dw.max.x) - dw.min.x + 1, H = int64_t(dw.max.y) - dw.min.y + 1;
        // Far beyond any image this tool writes; refuses absurd allocations from a bad header.
        if (W < 1 || H < 1 || W * H > (int64_t(1) << 30)) {
            OPENVDB_THROW(openvdb::IoError, "OpenEXR image has an unusable data window "
                << W << " x " << H);
        }
        const Imf::ChannelList& channels = file.header().channels();
        const bool rgb = channels.findChannel("R") || channels.findChannel("G")
            || channels.findChannel("B");
        const bool grey = !rgb && channels.findChannel("Y");
        if (!rgb && !grey) {
            OPENVDB_THROW(openvdb::IoError, "OpenEXR image has no R, G, B or Y channel");
        }
        Image image;
        image.width = int(W);
        image.height = int(H);
        image.pixels.assign(size_t(W * H), openvdb::Vec3f(0.f));
        char* base = reinterpret_cast<char*>(image.pixels.data());
        Imf::FrameBuffer fb;
        const char* names[3] = {"R", "G", "B"};
        for (int c = 0; c < (grey ? 1 : 3); ++c) {
            // Slice::Make maps the data window's origin onto the first pixel.
            fb.insert(grey ? "Y" : names[c], Imf::Slice::Make(Imf::FLOAT,
                base + size_t(c) * sizeof(float), dw, sizeof(openvdb::Vec3f),
                sizeof(openvdb::Vec3f) * size_t(W)));
        }
        file.setFrameBuffer(fb);
        file.readPixels(dw.min.y, dw.max.y);
        if (grey) {
            for (auto& p : image.pixels) p = openvdb::Vec3f(p[0]);
        }
        return image;
    } catch (const openvdb::Exception&) {
        throw;
    } catch (const std::exception& e) {
        OPENVDB_THROW(openvdb::IoError, "not a readable OpenEXR image: " << e.what());
    }
}

// ---- tone mapping and PNG ----------------------------------------------------------------------

double
srgbEncode(double v)
{
    return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
}

double
toneMapScale(const Image& image, const ToneMap& toneMap)
{
    checkImage(image);
    if (!std::isfinite(toneMap.exposureStops)) {
        OPENVDB_THROW(openvdb::ValueError, "exposure must be finite, got "
            << toneMap.exposureStops);
    }
    if (!(toneMap.percentile >= 0.0 && toneMap.percentile <= 1.0)) {
        OPENVDB_THROW(openvdb::ValueError, "tone-map percentile must be in [0, 1], got "
            << toneMap.percentile);
    }
    if (!(toneMap.key > 0.0) || !std::isfinite(toneMap.key)) {
        OPENVDB_THROW(openvdb::ValueError, "tone-map key must be positive, got " << toneMap.key);
    }
    double scale = std::exp2(toneMap.exposureStops);
    if (!toneMap.autoExposure) return scale;
    std::vector<float> lum;
    lum.reserve(image.pixels.size());
    for (size_t i = 0; i < image.pixels.size(); ++i) {
        if (!image.coverage.empty() && !(image.coverage[i] > 0.f)) continue;
        const openvdb::Vec3f& p = image.pixels[i];
        const float y = 0.2126f * p[0] + 0.7152f * p[1] + 0.0722f * p[2];
        lum.push_back(std::isfinite(y) ? y : 0.f);
    }
    if (lum.empty()) return scale;
    const size_t k = size_t(toneMap.percentile * double(lum.size() - 1));
    std::nth_element(lum.begin(), lum.begin() + long(k), lum.end());
    const double y = lum[k];
    return y > 0.0 ? scale * toneMap.key / y : scale;
}

std::string
encodePng(const Image& image, const ToneMap& toneMap)
{
    const double scale = toneMapScale(image, toneMap);   // checks the image and the tone map
    const size_t W = size_t(image.width), H = size_t(image.height);

    // Raw scanlines, each led by filter type 0 (none): previews are small, simplicity wins.
    std::string raw;
    raw.resize(H * (1 + 3 * W));
    size_t at = 0;
    for (size_t y = 0; y < H; ++y) {
        raw[at++] = 0;
        for (size_t x = 0; x < W; ++x) {
            const openvdb::Vec3f& p = image.pixels[y * W + x];
            for (int c = 0; c < 3; ++c) {
                double v = double(p[c]) * scale;
                if (!(v > 0.0)) v = 0.0;   // NaN too
                raw[at++] = char(uint8_t(std::lround(255.0 * srgbEncode(std::min(v, 1.0)))));
            }
        }
    }
    uLongf packedSize = compressBound(uLong(raw.size()));
    std::string packed(packedSize, '\0');
    if (compress2(reinterpret_cast<Bytef*>(&packed[0]), &packedSize,
            reinterpret_cast<const Bytef*>(raw.data()), uLong(raw.size()), 6) != Z_OK) {
        OPENVDB_THROW(openvdb::IoError, "zlib could not compress the PNG image data");
    }
    packed.resize(packedSize);

    std::string png("\x89PNG\r\n\x1a\n", 8);
    std::string ihdr;
    putU32(ihdr, uint32_t(W));
    putU32(ihdr, uint32_t(H));
    // 8 bits per channel, RGB, deflate, filter method 0, no interlace.
    ihdr += std::string("\x08\x02\x00\x00\x00", 5);
    putChunk(png, "IHDR", ihdr);
    putChunk(png, "sRGB", std::string(1, '\0'));        // perceptual rendering intent
    std::string gama;
    putU32(gama, 45455);                                // 1 / 2.2, for readers without sRGB
    putChunk(png, "gAMA", gama);
    putChunk(png, "IDAT", packed);
    putChunk(png, "IEND", std::string());
    return png;
}

} // namespace vdbrad
