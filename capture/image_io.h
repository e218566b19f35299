#pragma once
/// Image reading and writing that names the file in every error.
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace mrgi::capture {

/// Reads an 8-bit colour image as RGB (CV_8UC3). Throws CaptureError("<path>: ...") if missing/corrupt.
cv::Mat readColour(const std::string& path);
/// Reads a depth image and converts it to metres (CV_32FC1, 0 = invalid):
///  16-bit PNG/PGM: value * unitsMetres (0 stays 0);  32-bit float (TIFF/EXR): metres as stored.
/// NaN, inf or negative values in a float file are rejected as corrupt.
cv::Mat readDepth(const std::string& path, double unitsMetres);
/// Reads any image unchanged (fisheye frames: 8-bit RGB or float HDR), RGB channel order. EXR is decoded
/// by OpenEXR from memory (validated first); PNG by libpng; others by OpenCV with its output silenced.
cv::Mat readAny(const std::string& path);

/// Depth in metres -> 16-bit units (rounded; 0 and values beyond 65535 units become 0 = invalid).
cv::Mat depthToUnits(const cv::Mat& depthMetres, double unitsMetres);
/// Encodes an RGB or grey image (8/16-bit) to PNG bytes; throws CaptureError on failure.
std::vector<unsigned char> encodePng(const cv::Mat& image, const std::string& nameForErrors);
/// Encodes an 8-bit RGB or grey image to JPEG bytes at `quality` (1-100); throws CaptureError on failure.
std::vector<unsigned char> encodeJpeg(const cv::Mat& image, int quality, const std::string& nameForErrors);

/// Encodes a 32-bit float RGB (or grey) image to OpenEXR bytes in memory (ZIP; half or full float).
std::vector<unsigned char> encodeExr(const cv::Mat& rgb, bool half, const std::string& nameForErrors);

/// True for a path whose extension names an image format the readers decode (.png .jpg .jpeg .bmp .pgm
/// .ppm .tif .tiff, any case).
bool isImageFile(const std::filesystem::path& path);

/// Writes bytes to "<path>.tmp", fsyncs, then renames over path: readers see the whole file or nothing.
/// Throws CaptureError naming the path.
void writeFileAtomically(const std::filesystem::path& path, const std::vector<unsigned char>& bytes);
/// The same for text (JSON documents, manifests).
void writeFileAtomically(const std::filesystem::path& path, const std::string& text);

/// Silences OpenCV's own logging so a bad file produces our one-line error only.
void quietOpenCv();

}  // namespace mrgi::capture
