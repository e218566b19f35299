# Script mode: writes OUT, a C++ file registering the text of IN under NAME in the shader registry.
file(READ ${IN} text)
# Split into chunks below the 16 KiB string-literal limit some compilers have; a raw string delimiter that
# cannot occur in GLSL keeps the text verbatim.
string(LENGTH "${text}" len)
set(chunks "")
set(pos 0)
while(pos LESS len)
  string(SUBSTRING "${text}" ${pos} 8000 piece)
  string(APPEND chunks "R\"mrgi_glsl(${piece})mrgi_glsl\"\n")
  math(EXPR pos "${pos} + 8000")
endwhile()
if(chunks STREQUAL "")
  set(chunks "\"\"")
endif()
file(WRITE ${OUT} "// Generated from ${NAME} by cmake/EmbedShader.cmake. Do not edit.\n#include \"gl/shader_registry.h\"\nnamespace {\nconst mrgi::gl::ShaderRegistration kReg_${IDENT}{\"${NAME}\",\n${chunks}};\n}\n")
