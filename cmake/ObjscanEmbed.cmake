# objscan_embed_text(HEADER NAMESPACE VARIABLE FILE): writes HEADER, a header that holds FILE's
# text as `inline constexpr std::string_view VARIABLE` in NAMESPACE, so that a page or script
# objscan serves is compiled into the binary (no CDN, no install path to find at run time).
# Re-run when FILE changes. A text longer than 64 kB needs -Wno-overlength-strings where the
# header is included (GCC reads any length; -Wpedantic only warns past the standard's minimum).
function(objscan_embed_text header namespace variable file)
  set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS "${file}")
  file(READ "${file}" content)
  string(FIND "${content}" ")objscan_text\"" clash)
  if(NOT clash EQUAL -1)
    message(FATAL_ERROR "${file} holds the raw-string delimiter objscan_embed_text uses")
  endif()
  file(WRITE "${header}.new"
    "#pragma once\n// Generated from ${file} by objscan_embed_text: do not edit.\n"
    "#include <string_view>\nnamespace ${namespace} {\n"
    "inline constexpr char ${variable}Text[] = R\"objscan_text(${content})objscan_text\";\n"
    "// The length from the array, not by counting: a constexpr count of a long text exceeds GCC's\n"
    "// constexpr loop limit.\n"
    "inline constexpr std::string_view ${variable}{${variable}Text, sizeof ${variable}Text - 1};\n"
    "}  // namespace ${namespace}\n")
  configure_file("${header}.new" "${header}" COPYONLY)
endfunction()
