#include "json_nesting.h"

namespace probebake::job_internal {

bool JsonNestsDeeperThan(std::string_view json, int levels) {
  int depth = 0;
  bool inString = false;
  for (size_t k = 0; k < json.size(); ++k) {
    const char c = json[k];
    if (inString) {
      if (c == '\\') {
        ++k;  // the escaped character cannot end the string
      } else if (c == '"') {
        inString = false;
      }
    } else if (c == '"') {
      inString = true;
    } else if (c == '[' || c == '{') {
      if (++depth > levels) return true;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return false;
}

}  // namespace probebake::job_internal
