// A walk over an OpenVDB file's header, file metadata, grid descriptors and grid metadata before
// OpenVDB reads them.
//
// OpenVDB sizes strings and metadata values by the lengths the file declares and fills them
// before reading (a damaged 100 kB file can make it allocate and zero gigabytes, for minutes);
// this walk checks every declared length against the bytes the file holds, every fixed-size
// metadata value's declared size against its type's (OpenVDB reads sizeof(T) whatever is
// declared), OpenVDB's delayed-load counts against the file's size, and every grid's offsets
// against the file's size, first. It reads nothing a length has not been checked for. Metadata of
// types OpenVDB does not register for plain values (anything but bool, int32, int64, float,
// double, string, vec2/3/4 i/s/d, mat4s/d and OpenVDB's own delayed-load record) is refused.
#pragma once

#include <string>

namespace probebake::volume_internal {

// "" when the file's header, metadata and grid descriptors fit in the file, else a sentence
// saying what does not ("grid descriptor 3's type declares 2147483647 bytes; 412 are left").
// Files without grid offsets (a stream written non-seekable) are refused: every writer of files
// this reader takes (probebake's, OpenVDB's File::write) writes them.
std::string VdbFileProblem(const std::string& path);

}  // namespace probebake::volume_internal
