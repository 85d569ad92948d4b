// Assimp's warnings, seen per import (private to core/src/job). Some importers repair a fault and
// say so only in a log line: glTF drops triangles whose indices exceed its vertices ("Some faces
// had out-of-range indices. Those faces were dropped."), which would bake a model with holes
// without a word. A capture collects the warnings assimp logs on the calling thread while it
// lives, so the import can refuse such a file as OBJ and PLY imports refuse the same fault.
#pragma once

#include <string>
#include <vector>

namespace probebake::job_internal {

class AssimpWarningCapture {
 public:
  // Installs assimp's default logger on first use (warnings and errors only); captures nest not.
  AssimpWarningCapture();
  ~AssimpWarningCapture();
  AssimpWarningCapture(const AssimpWarningCapture&) = delete;
  AssimpWarningCapture& operator=(const AssimpWarningCapture&) = delete;

  // The warnings logged on this thread since construction, in order.
  const std::vector<std::string>& warnings() const;
  // True when a warning contains `text`.
  bool Saw(const std::string& text) const;
};

}  // namespace probebake::job_internal
