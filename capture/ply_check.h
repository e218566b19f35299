#pragma once
/// PLY files are checked before any reader sees them (assimp for models, Open3D for room meshes): header
/// grammar, and a body holding every element the header declares.
#include <string>

namespace mrgi::capture {

/// Throws InputError naming the file when a PLY file (named .ply or starting with "ply") has a malformed
/// header or a body shorter than its header declares. Files that are not PLY are left alone.
void checkPlyFile(const std::string& path);

}  // namespace mrgi::capture
