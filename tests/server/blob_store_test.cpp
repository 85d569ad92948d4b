#include "server/blob_store.h"

#include <gtest/gtest.h>

#include <fstream>

#include "probebake/job/digest.h"
#include "temp_dir.h"

namespace probebake::server {
namespace {

using probebake::testing::TempDir;

std::string Bytes(size_t n, uint32_t seed) {
  std::string s(n, '\0');
  uint32_t x = seed;
  for (char& c : s) {
    x = x * 1664525u + 1013904223u;
    c = char(x >> 24);
  }
  return s;
}

std::unique_ptr<BlobStore> OpenStore(const TempDir& dir, int64_t maxBytes = 1 << 24) {
  auto store = BlobStore::Open(dir.path(), maxBytes);
  EXPECT_TRUE(store.ok()) << store.status();
  return std::move(*store);
}

TEST(BlobStore, WriteThenReadBackInChunks) {
  TempDir dir;
  auto store = OpenStore(dir);
  std::string data = Bytes(300000, 1);
  v1::Digest digest = DigestOf(data);
  EXPECT_FALSE(store->Contains(digest));
  auto upload = store->BeginWrite(digest);
  ASSERT_TRUE(upload.ok()) << upload.status();
  for (size_t offset = 0; offset < data.size(); offset += 65536)
    ASSERT_TRUE(
        (*upload)->Append(int64_t(offset), std::string_view(data).substr(offset, 65536)).ok());
  ASSERT_TRUE((*upload)->Commit().ok());
  upload->reset();
  EXPECT_TRUE(store->Contains(digest));
  // The stored file is the content under its hash, and nothing is left in uploads/.
  EXPECT_TRUE(std::filesystem::is_empty(dir.path() / "uploads"));
  auto all = store->ReadAll(digest);
  ASSERT_TRUE(all.ok()) << all.status();
  EXPECT_EQ(*all, data);
  auto reader = store->OpenRead(digest);
  ASSERT_TRUE(reader.ok());
  std::string part;
  ASSERT_TRUE((*reader)->ReadAt(299990, 100, &part).ok());
  EXPECT_EQ(part, data.substr(299990));
}

TEST(BlobStore, WrongHashIsInvalidArgumentAndDiscarded) {
  TempDir dir;
  auto store = OpenStore(dir);
  std::string data = Bytes(1000, 2);
  v1::Digest digest = DigestOf(data);
  data[10] ^= 1;
  auto upload = store->BeginWrite(digest);
  ASSERT_TRUE(upload.ok());
  ASSERT_TRUE((*upload)->Append(0, data).ok());
  absl::Status committed = (*upload)->Commit();
  EXPECT_EQ(committed.code(), absl::StatusCode::kInvalidArgument) << committed;
  EXPECT_NE(std::string(committed.message()).find("digest.hash"), std::string::npos) << committed;
  upload->reset();
  EXPECT_FALSE(store->Contains(digest));
  bool complete = true;
  EXPECT_EQ(store->CommittedSize(digest, &complete).value_or(-1), 0);
  EXPECT_FALSE(complete);
}

TEST(BlobStore, OffsetsAndSizesAreChecked) {
  TempDir dir;
  auto store = OpenStore(dir, 5000);
  std::string data = Bytes(1000, 3);
  v1::Digest digest = DigestOf(data);
  auto upload = store->BeginWrite(digest);
  ASSERT_TRUE(upload.ok());
  EXPECT_EQ((*upload)->Append(5, data.substr(0, 10)).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ((*upload)->Append(0, data + "x").code(), absl::StatusCode::kInvalidArgument);
  // A second upload of the same digest while this one is open.
  EXPECT_EQ(store->BeginWrite(digest).status().code(), absl::StatusCode::kAborted);
  upload->reset();
  v1::Digest huge = DigestOf(Bytes(6000, 4));
  EXPECT_EQ(store->BeginWrite(huge).status().code(), absl::StatusCode::kInvalidArgument);
  v1::Digest bad;
  bad.set_hash("ABC");
  EXPECT_EQ(store->BeginWrite(bad).status().code(), absl::StatusCode::kInvalidArgument);
  bad.set_hash(std::string(64, 'A'));
  EXPECT_EQ(ValidateDigest(bad, "d").code(), absl::StatusCode::kInvalidArgument);
  bad.set_hash(std::string(64, 'a'));
  bad.set_size_bytes(-1);
  EXPECT_EQ(ValidateDigest(bad, "d").code(), absl::StatusCode::kInvalidArgument);
}

TEST(BlobStore, InterruptedUploadResumesFromCommittedSize) {
  TempDir dir;
  std::string data = Bytes(250000, 5);
  v1::Digest digest = DigestOf(data);
  {
    auto store = OpenStore(dir);
    auto upload = store->BeginWrite(digest);
    ASSERT_TRUE(upload.ok());
    ASSERT_TRUE((*upload)->Append(0, data.substr(0, 100000)).ok());
    // Asked while the upload is open (QueryWriteStatus from another call): synced, then counted.
    bool complete = true;
    EXPECT_EQ(store->CommittedSize(digest, &complete).value_or(-1), 100000);
    EXPECT_FALSE(complete);
    // Dropped without Commit: the bytes stay.
  }
  auto store = OpenStore(dir);  // a restarted server
  bool complete = true;
  EXPECT_EQ(store->CommittedSize(digest, &complete).value_or(-1), 100000);
  EXPECT_FALSE(complete);
  auto upload = store->BeginWrite(digest);
  ASSERT_TRUE(upload.ok());
  EXPECT_EQ((*upload)->committedSize(), 100000);
  ASSERT_TRUE((*upload)->Append(100000, data.substr(100000)).ok());
  // The hash spans both sessions: a wrong prefix would fail here.
  ASSERT_TRUE((*upload)->Commit().ok());
  upload->reset();
  EXPECT_EQ(store->CommittedSize(digest, &complete).value_or(-1), int64_t(data.size()));
  EXPECT_TRUE(complete);
  EXPECT_EQ(*store->ReadAll(digest), data);
}

TEST(BlobStore, FindMissingAndSizeMismatch) {
  TempDir dir;
  auto store = OpenStore(dir);
  std::string data = Bytes(100, 6);
  v1::Digest present = DigestOf(data), absent = DigestOf(Bytes(100, 7));
  auto upload = store->BeginWrite(present);
  ASSERT_TRUE((*upload)->Append(0, data).ok());
  ASSERT_TRUE((*upload)->Commit().ok());
  upload->reset();
  auto missing = store->FindMissing({present, absent, absent});
  ASSERT_EQ(missing.size(), 1u);
  EXPECT_EQ(missing[0].hash(), absent.hash());
  // The same hash with another size is not the stored blob; reading it is DATA_LOSS.
  v1::Digest wrongSize = present;
  wrongSize.set_size_bytes(99);
  EXPECT_FALSE(store->Contains(wrongSize));
  EXPECT_EQ(store->OpenRead(wrongSize).status().code(), absl::StatusCode::kDataLoss);
  EXPECT_EQ(store->OpenRead(absent).status().code(), absl::StatusCode::kNotFound);
}

TEST(BlobStore, ImportFileStoresUnderItsHash) {
  TempDir dir;
  auto store = OpenStore(dir);
  std::string data = Bytes(5000, 8);
  std::filesystem::path file = store->tmpDir() / "result.vdb";
  std::ofstream(file, std::ios::binary) << data;
  auto digest = store->ImportFile(file);
  ASSERT_TRUE(digest.ok()) << digest.status();
  EXPECT_EQ(digest->hash(), Sha256Hex(data));
  EXPECT_EQ(digest->size_bytes(), 5000);
  EXPECT_FALSE(std::filesystem::exists(file));
  EXPECT_EQ(*store->ReadAll(*digest), data);
}

}  // namespace
}  // namespace probebake::server
