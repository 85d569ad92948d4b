#include <gtest/gtest.h>

#include "probebake/base/status.h"

namespace probebake {
namespace {

absl::StatusOr<int> Half(int x) {
  if (x % 2) return FieldError("x", "odd");
  return x / 2;
}

absl::Status Quarter(int x, int* out) {
  PB_ASSIGN_OR_RETURN(int h, Half(x));
  PB_ASSIGN_OR_RETURN(*out, Half(h));
  return absl::OkStatus();
}

TEST(Status, FieldErrorNamesThePath) {
  const absl::Status s = FieldError("scene.lights[2].rect.edge1", "zero length");
  EXPECT_EQ(s.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(s.message(), "scene.lights[2].rect.edge1: zero length");
}

TEST(Status, AssignOrReturnPropagates) {
  int q = 0;
  EXPECT_TRUE(Quarter(8, &q).ok());
  EXPECT_EQ(q, 2);
  const absl::Status s = Quarter(6, &q);
  EXPECT_EQ(s.message(), "x: odd");
}

}  // namespace
}  // namespace probebake
