# The three.js plugin with its shader: web/csrbf_deformation.js.in with @CSRBF_GLSL@ replaced by the
# text of web/csrbf_deformation.glsl, so that the GLSL has one source (engines read the .glsl file).
#   cmake -DTEMPLATE=csrbf_deformation.js.in -DGLSL=csrbf_deformation.glsl -DOUT=csrbf_deformation.js -P embed_glsl.cmake
file(READ "${GLSL}" glsl)
# The text goes into a JavaScript template literal: a backquote, a backslash or "${" would end or
# change it.
string(FIND "${glsl}" "`" backquote)
string(FIND "${glsl}" "\\" backslash)
string(FIND "${glsl}" "\${" substitution)
if(NOT backquote EQUAL -1 OR NOT backslash EQUAL -1 OR NOT substitution EQUAL -1)
  message(FATAL_ERROR "${GLSL}: a backquote, a backslash or '\${' cannot go into the JavaScript template literal")
endif()
file(READ "${TEMPLATE}" js)
string(FIND "${js}" "@CSRBF_GLSL@" at)
if(at EQUAL -1)
  message(FATAL_ERROR "${TEMPLATE}: no @CSRBF_GLSL@ to replace")
endif()
string(REPLACE "@CSRBF_GLSL@" "${glsl}" js "${js}")
file(WRITE "${OUT}.tmp" "${js}")
file(RENAME "${OUT}.tmp" "${OUT}")
