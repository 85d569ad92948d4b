// Structural checks of mesh files before assimp reads them (private to core/src/job).
//
// Assimp trusts the sizes a file declares: fuzzed PLY files crashed it (a NUL byte in the header)
// or made it run for ever (no end_header line; an element count of 10^11; a list property whose
// count, read from garbage, is huge), and a GLB chunk declaring 4 GiB had it allocate and clear
// 4 GiB. These checks accept only files whose declared parts fit in the bytes that are there.
#pragma once

#include <string>
#include <string_view>

namespace probebake::job_internal {

// "" when `bytes` is a structurally sound PLY file: a text header of "ply", one known format line
// (ascii, binary_little_endian or binary_big_endian, version 1.0), element and property lines of
// known types (list counts of an integer type), comments, and an end_header line within the first
// MiB; then a body holding every element instance the header declares (binary: the exact bytes,
// list counts non-negative; ascii: enough numbers, list counts non-negative integers). Trailing
// bytes are allowed; no triangle strips (element 'tristrips', which assimp misreads). Otherwise
// the reason, for a message ("its header has no end_header line").
std::string PlyProblem(std::string_view bytes);

// "" when `bytes` is a GLB container whose declared sizes fit: magic "glTF", version 1 or 2, a
// total length no larger than the file, and (version 2) chunks that each fit in that length, the
// first of them JSON that passes GltfProblem; (version 1)
// content that fits. Otherwise the reason.
std::string GlbProblem(std::string_view bytes);

// "" unless the glTF JSON `json` (a .gltf file, or a GLB's JSON chunk) holds something assimp
// would read badly, slowly or through the file system:
//   - a node graph that is not a forest: a child index out of range, a node with two parents (each
//     level doubling the scene: 22 levels took 2.7 GB before assimp was stopped), a cycle, or
//     nesting deeper than 1000 (JSON nesting deeper than 100 is refused before parsing);
//   - a buffer outside itself, a uri that is not a data: URI: assimp would open it through the
//     file system, which a bake never lets it do (a server must not open a path a request names,
//     docs/service.md); the reason says so and how to embed it;
//   - geometry assimp reads wrong without a word: the extensions KHR_mesh_quantization,
//     EXT_meshopt_compression and KHR_meshopt_compression (int16 positions read as floats), a
//     triangle list whose index or vertex count is not a multiple of 3 (the rest dropped), a node
//     whose morph target weights (its own, else its mesh's) are not all zero (not applied).
// JSON this check cannot parse is left to assimp.
std::string GltfProblem(std::string_view json);

// The check of `format` ("ply", "glb", "gltf"; "" for formats without one, such as obj).
std::string MeshFileProblem(std::string_view bytes, const std::string& format);

}  // namespace probebake::job_internal
