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
  // room for it with as much again to spare; true when it holds something now. Never fails
  // loudly: without room the reserve stays as it is (logged once).
  bool Restore();
  // Removes the file; true when that gave space back (false when nothing was held).
  bool Release();
  // After a Release, once the write that needed the space is done: takes back what is free, up
  // to `bytes`, even if that leaves nothing for others, since the reserve is only lent to the
  // job store (whole MiB, at least one). True when it holds something now.
  bool Retake();
  bool held() const;

 private:
  bool AllocateLocked(int64_t bytes);

  const std::filesystem::path path_;
  const int64_t bytes_;
  mutable std::mutex mutex_;
  bool held_ = false;
  bool warnedNoRoom_ = false;
};

}  // namespace probebake::server
