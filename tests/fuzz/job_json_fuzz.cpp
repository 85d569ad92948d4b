// Job files: JSON parsing (protobuf's mapping behind the nesting guard) and validation.
#include <cstddef>
#include <cstdint>
#include <string>

#include "probebake/job/job_json.h"
#include "probebake/job/limits.h"
#include "probebake/job/validate.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string json(reinterpret_cast<const char*>(data), size);
  const auto spec = probebake::ParseJobJson(json);
  if (spec.ok()) (void)probebake::ValidateJobSpec(*spec, probebake::JobLimits());
  return 0;
}
