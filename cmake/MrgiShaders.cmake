# mrgi_embed_shaders(TARGET BASE_DIR FILES...)
# Embeds GLSL files (.vert/.frag/.comp/.glsl) into TARGET. Each file is registered under its path relative
# to BASE_DIR (e.g. "compositor/composite.frag") in mrgi::gl's shader registry at static-initialisation time.
# For a library the registrations go into an object library whose objects are linked straight into every
# executable using TARGET, so the linker cannot drop them as unreferenced archive members.
function(mrgi_embed_shaders target base_dir)
  set(out_dir ${CMAKE_CURRENT_BINARY_DIR}/embedded_shaders)
  set(generated)
  foreach(file ${ARGN})
    get_filename_component(abs ${file} ABSOLUTE)
    file(RELATIVE_PATH rel ${base_dir} ${abs})
    string(MAKE_C_IDENTIFIER ${rel} ident)
    set(out ${out_dir}/${ident}.cpp)
    add_custom_command(
      OUTPUT ${out}
      COMMAND ${CMAKE_COMMAND} -DIN=${abs} -DOUT=${out} -DNAME=${rel} -DIDENT=${ident}
              -P ${PROJECT_SOURCE_DIR}/cmake/EmbedShader.cmake
      DEPENDS ${abs} ${PROJECT_SOURCE_DIR}/cmake/EmbedShader.cmake
      COMMENT "Embedding shader ${rel}")
    list(APPEND generated ${out})
  endforeach()
  get_target_property(type ${target} TYPE)
  if(type STREQUAL "EXECUTABLE")
    target_sources(${target} PRIVATE ${generated})
  else()
    add_library(${target}_shaders OBJECT ${generated})
    if(target STREQUAL "mrgi_gl")  # the registry's own library: its header, without a link back to it
      target_include_directories(${target}_shaders PRIVATE ${PROJECT_SOURCE_DIR}/lighting)
    else()
      target_link_libraries(${target}_shaders PRIVATE mrgi_gl)
    endif()
    target_sources(${target} INTERFACE $<TARGET_OBJECTS:${target}_shaders>)
    add_dependencies(${target} ${target}_shaders)
  endif()
endfunction()
