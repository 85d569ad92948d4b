// Disk space held back in the data folder for the job store. On a full disk the store cannot
// record anything (SQLite needs room to write), so a job could not be cancelled or deleted, the
// collector could not free space by deleting, and a restarted server could not open its store.
// The reserve is a file of real blocks given back at that moment and taken again once the disk
// has room.
#pragma once

#include <cstdint>
#include <filesystem>
#include <mutex>

namespace probebake::server {

class DiskReserve {
 public:
  // Holds nothing until Restore. `bytes` 0: never holds anything.
  DiskReserve(std::filesystem::path path, int64_t bytes);

  // Makes the file hold `bytes` (allocated, not sparse) when it does not and the file system has
  // room for it with as much again to spare; true when it holds them now. Never fails loudly:
  // without room there is simply no reserve (logged).
  bool Restore();
  // Removes the file; true when that gave space back (false when nothing was held).
  bool Release();
  bool held() const;

 private:
  const std::filesystem::path path_;
  const int64_t bytes_;
  mutable std::mutex mutex_;
  bool held_ = false;
};

}  // namespace probebake::server
