// A walk over a whole OpenVDB file, header to the last leaf buffer, before OpenVDB reads it.
//
// OpenVDB sizes strings, metadata values and node buffers by what the file declares and fills
// them before checking (a damaged 100 kB file can make it allocate and zero gigabytes, for
// minutes, or copy a chunk past a leaf's buffer); this walk checks every declared length against
// the bytes the file holds, every fixed-size metadata value's declared size against its type's
// (OpenVDB reads sizeof(T) whatever is declared), OpenVDB's delayed-load counts against the file's
// size, every grid's offsets against the file's size, and every grid's body (vdb_tree_walk.h),
// first. It reads nothing a length has not been checked for. Metadata of types OpenVDB does not
// register for plain values (anything but bool, int32, int64, float, double, string, vec2/3/4
// i/s/d, mat4s/d and OpenVDB's own delayed-load record) is refused, and so are grids other than
// numeric 5-4-3 trees with a linear transform, and files older than format 222 (OpenVDB 2.0).
#pragma once

#include <string>

namespace probebake::volume_internal {

// "" when the file's header, metadata, grid descriptors and grids fit in the file, else a sentence
// saying what does not ("grid descriptor 3's type declares 2147483647 bytes; 412 are left").
// Files without grid offsets (a stream written non-seekable) are refused: every writer of files
// this reader takes (probebake's, OpenVDB's File::write) writes them.
std::string VdbFileProblem(const std::string& path);

}  // namespace probebake::volume_internal
