// NumPy's .npz archive, written from C++ (`[output] format = "npz"`): what np.savez writes — an
// uncompressed ZIP (libzip; ZIP64 when large) of one .npy file per array — so that np.load,
// fracvi.load and `fracvi plot` read it as they read fracvi.write's.
//
// The .npy format (NEP 1, version 1.0): the magic "\x93NUMPY", the version, a little-endian
// uint16 header length, then a Python dict literal {'descr': '<f8', 'fortran_order': False,
// 'shape': (rows, cols), } padded with spaces and a newline so that the data starts at a multiple
// of 64 bytes, then the data in C order. Hand-written: no Debian library writes .npy.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace fracvi {

/// One array of an .npz archive: `name` (the member is name + ".npy"), C-ordered data of
/// `shape` (one entry for a vector, two for a matrix), doubles or 64-bit integers.
struct NpyArray {
  std::string name;
  std::vector<std::size_t> shape;
  const double* doubles = nullptr;         ///< '<f8' data, or
  const std::int64_t* integers = nullptr;  ///< '<i8' data
};

/// The .npy file of `array`: header and data.
std::string npy_file(const NpyArray& array);

/// Writes `arrays` as the .npz archive `file`, through a temporary `<file>.tmp.<pid>.<n>` renamed
/// at the end (write_file_atomically's naming: a crash never leaves a partial file under the
/// final name). Throws OutputError naming the file and libzip's reason.
void write_npz(const std::filesystem::path& file, std::span<const NpyArray> arrays);

}  // namespace fracvi
