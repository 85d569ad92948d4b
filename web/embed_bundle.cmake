# cmake -DINPUT=viewer.bundle.js -DOUTPUT=viewer_bundle.cpp -P embed_bundle.cmake
# Embeds the bundle as probebake::kViewerBundle, in raw-string pieces of at most 60000 bytes
# (compilers cap a single string literal; adjacent literals concatenate).
file(READ ${INPUT} js)
string(LENGTH "${js}" n)
set(out "#include <string_view>\nnamespace probebake {\nextern const std::string_view kViewerBundle;\nstatic const char kBundleText[] =\n")
set(pos 0)
while(pos LESS n)
  string(SUBSTRING "${js}" ${pos} 60000 piece)
  string(APPEND out "R\"pbview(${piece})pbview\"\n")
  math(EXPR pos "${pos} + 60000")
endwhile()
string(APPEND out ";\nconst std::string_view kViewerBundle(kBundleText, sizeof(kBundleText) - 1);\n}  // namespace probebake\n")
file(WRITE ${OUTPUT} "${out}")
