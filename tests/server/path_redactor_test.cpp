#include "server/path_redactor.h"

#include <gtest/gtest.h>

#include "absl/strings/str_cat.h"

#include "temp_dir.h"

namespace probebake::server {
namespace {

TEST(PathRedactor, NamesTheDataFolderDataInEveryFormAndNothingElse) {
  testing::TempDir dir;
  const std::filesystem::path data = dir.path() / "data";
  std::filesystem::create_directories(data);
  const PathRedactor redact(data);
  EXPECT_EQ(redact("open " + data.string() + "/blobs/ab/abc: Permission denied"),
            "open DATA/blobs/ab/abc: Permission denied");
  EXPECT_EQ(redact(absl::StrCat("'", data.string(), "': not a file path")),
            "'DATA': not a file path");
  EXPECT_EQ(redact(data.string() + "/tmp/x.vdb and " + data.string() + "/tmp/y.vdb"),
            "DATA/tmp/x.vdb and DATA/tmp/y.vdb");
  // Another folder that merely starts with the same name, and words, are left alone.
  EXPECT_EQ(redact(data.string() + "2/x"), data.string() + "2/x");
  EXPECT_EQ(redact("sqlite: database is locked"), "sqlite: database is locked");
  // The status form keeps the code.
  const absl::Status status = redact(absl::InternalError("rename " + data.string() + "/tmp/a"));
  EXPECT_EQ(status.code(), absl::StatusCode::kInternal);
  EXPECT_EQ(status.message(), "rename DATA/tmp/a");
  EXPECT_TRUE(redact(absl::OkStatus()).ok());
}

TEST(PathRedactor, ARelativeFolderIsRedactedWhereItStandsAsAPath) {
  const PathRedactor redact("data");
  EXPECT_EQ(redact("open data/blobs/x: No space left on device"),
            "open DATA/blobs/x: No space left on device");
  EXPECT_EQ(redact("database or disk is full in data/jobs.sqlite"),
            "database or disk is full in DATA/jobs.sqlite");
  EXPECT_EQ(redact("/srv/other/data/x"), "/srv/other/data/x");  // a different folder
  // Its absolute form too.
  const std::string absolute = std::filesystem::absolute("data").string();
  EXPECT_EQ(redact("open " + absolute + "/tmp/t"), "open DATA/tmp/t");
}

TEST(PathRedactor, ADefaultOneChangesNothing) {
  EXPECT_EQ(PathRedactor()("open /srv/data/x"), "open /srv/data/x");
}

}  // namespace
}  // namespace probebake::server
