// A walk over one grid's body (transform, tree topology, leaf buffers) as OpenVDB 10 reads it
// (io::Archive::readGrid), before OpenVDB does.
//
// OpenVDB trusts a grid body's counts and chunk sizes: io::bloscFromStream and unzipFromStream
// copy a chunk marked uncompressed at the length the file declares into a node buffer sized by
// the tree, and check the length only afterwards (a heap overflow from a damaged file). This walk
// follows the same bytes with the tree's own sizes and checks every one first: chunk lengths
// against the values the node holds, Blosc headers against the chunk, masks and counts against the
// file, root keys for alignment and uniqueness, booleans for 0 or 1, and the topology and buffers
// ending exactly where the grid descriptor says. Only the trees probebake and stock tools write
// for numeric grids are taken: the standard 5-4-3 configuration of float, double, int32, int64,
// vec3s, vec3d or vec3i values (half-float storage included), with a linear transform.
#pragma once

#include <cstdint>
#include <string>

#include "vdb_file_walker.h"

namespace probebake::volume_internal {

// One grid as its descriptor and header describe it.
struct GridBody {
  std::string what;          // "grid \"validity\"", for messages
  std::string type;          // the descriptor's tree type, e.g. "Tree_vec3s_5_4_3_HalfFloat"
  bool instance = false;     // an instance shares another grid's tree and stores none
  uint32_t compression = 0;  // the grid's io::COMPRESS_* flags
  uint64_t blockPos = 0;     // where the descriptor says the leaf buffers start
  uint64_t endPos = 0;       // and where the grid ends
};

// "" when the grid type is one this reader takes ("" also for an instance's missing tree), else
// a sentence naming what it is.
std::string GridTypeProblem(const GridBody& grid);

// Walks the grid body from the walker's position (just after the grid's metadata) to its end:
// "" when OpenVDB can read it within the sizes the tree implies, else a sentence naming the first
// field that does not fit ("grid \"sh_0\" leaf 3's values declare an uncompressed chunk of 4096
// bytes; the leaf holds 2048").
std::string WalkGridBody(FileWalker& w, const GridBody& grid);

}  // namespace probebake::volume_internal
