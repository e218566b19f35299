# Every dependency comes from a Debian package (tools/install-deps.sh installs them all).
find_package(PkgConfig REQUIRED)
find_package(Threads REQUIRED)
find_package(OpenCV 4 REQUIRED COMPONENTS core imgproc imgcodecs calib3d ximgproc photo rgbd quality videoio)
find_package(nlohmann_json 3 REQUIRED)
find_package(CLI11 REQUIRED)
find_package(glfw3 3.3 REQUIRED)
find_package(embree 3 REQUIRED)
find_package(assimp REQUIRED)
find_package(PNG REQUIRED)  # capture decodes PNG frames with its own error handlers (no libpng messages on the terminal)
find_package(JPEG REQUIRED)  # and JPEG the same way (libjpeg would print its warnings and return a partly grey image)
find_package(Open3D REQUIRED)  # the room model: ScalableTSDFVolume fusion, marching cubes, PLY mesh I/O
find_package(Python3 REQUIRED COMPONENTS Interpreter)

pkg_check_modules(OSMESA REQUIRED IMPORTED_TARGET osmesa)
pkg_check_modules(EGL REQUIRED IMPORTED_TARGET egl)
pkg_check_modules(OPENNI2 REQUIRED IMPORTED_TARGET libopenni2)
pkg_check_modules(OPENEXR REQUIRED IMPORTED_TARGET OpenEXR)  # EXR from and to memory (no temporary files)
pkg_check_modules(LIBV4L2 REQUIRED IMPORTED_TARGET libv4l2)
pkg_check_modules(APRILTAG REQUIRED IMPORTED_TARGET apriltag)
pkg_check_modules(IMGUI REQUIRED IMPORTED_TARGET imgui)  # Dear ImGui with its GLFW + OpenGL 3 backends

set(MRGI_GL_XML /usr/share/khronos-api/gl.xml CACHE FILEPATH "Khronos GL registry (package khronos-api)")
if(NOT EXISTS ${MRGI_GL_XML})
  message(FATAL_ERROR "gl.xml not found at ${MRGI_GL_XML}: install the khronos-api package (tools/install-deps.sh)")
endif()
