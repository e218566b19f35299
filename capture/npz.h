#pragma once
/// NumPy .npy arrays and uncompressed .npz archives (numpy.savez), as some public RGB-D datasets ship
/// depth. Only what depth needs: little-endian integer/float dtypes, C order, 1-3 dimensions.
#include <opencv2/core.hpp>
#include <string>

namespace mrgi::capture {

/// Parses a .npy byte buffer into a Mat (2-D arrays as rows x cols; a third dimension as channels).
/// Throws CaptureError naming `where` on any malformed or unsupported content.
cv::Mat parseNpy(const std::string& bytes, const std::string& where);

/// Reads array `name` (e.g. "data.npy") from an uncompressed .npz file.
cv::Mat readNpzArray(const std::string& path, const std::string& name);

}  // namespace mrgi::capture
