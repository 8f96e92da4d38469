// NumPy .npz archives: see npz.hpp.
#include "fracvi/io/npz.hpp"

#include <zip.h>

#include <bit>
#include <cstring>

#include "fracvi/io/output.hpp"

namespace fracvi {

static_assert(std::endian::native == std::endian::little,
              "the .npy data are written as stored: '<f8' and '<i8' need a little-endian machine");

std::string npy_file(const NpyArray& array) {
  std::string shape = "(";
  std::size_t count = 1;
  for (const std::size_t n : array.shape) {
    shape += std::to_string(n) + ", ";
    count *= n;
  }
  if (array.shape.size() != 1)
    shape.resize(shape.size() - 2);  // (n,) keeps its comma
  else
    shape.pop_back();
  shape += ")";
  std::string header = std::string("{'descr': '") + (array.doubles ? "<f8" : "<i8") +
                       "', 'fortran_order': False, 'shape': " + shape + ", }";
  // magic (6) + version (2) + length (2) + header + padding + '\n' ≡ 0 (mod 64)
  constexpr std::size_t kPrefix = 10, kAlign = 64;
  const std::size_t padded = (kPrefix + header.size() + 1 + kAlign - 1) / kAlign * kAlign;
  header.append(padded - kPrefix - header.size() - 1, ' ');
  header += '\n';
  const std::size_t length = header.size();  // < 65536: the version 1.0 field
  std::string file = "\x93NUMPY\x01";
  file += '\0';
  file += static_cast<char>(length & 0xffU);
  file += static_cast<char>(length >> 8U);
  file += header;
  const std::size_t bytes = count * 8;
  const std::size_t at = file.size();
  file.resize(at + bytes);
  if (bytes > 0) {
    std::memcpy(file.data() + at,
                array.doubles ? static_cast<const void*>(array.doubles) : array.integers, bytes);
  }
  return file;
}

void write_npz(const std::filesystem::path& file, std::span<const NpyArray> arrays) {
  const auto tmp = temporary_path(file);
  const auto fail = [&](const std::string& why) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw OutputError("cannot write " + file.string() + ": " + why);
  };
  int error = 0;
  zip_t* archive = zip_open(tmp.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &error);
  if (archive == nullptr) {
    zip_error_t e;
    zip_error_init_with_code(&e, error);
    const std::string why = zip_error_strerror(&e);
    zip_error_fini(&e);
    fail(why);
  }
  // The members' bytes must live until zip_close writes them.
  std::vector<std::string> members;
  members.reserve(arrays.size());
  for (const NpyArray& array : arrays) {
    members.push_back(npy_file(array));
    zip_source_t* source =
        zip_source_buffer(archive, members.back().data(), members.back().size(), 0);
    const std::string name = array.name + ".npy";
    const zip_int64_t index =
        source == nullptr ? -1 : zip_file_add(archive, name.c_str(), source, ZIP_FL_ENC_UTF_8);
    if (index < 0 ||
        zip_set_file_compression(archive, static_cast<zip_uint64_t>(index), ZIP_CM_STORE, 0) != 0) {
      const std::string why = zip_strerror(archive);
      if (index < 0 && source != nullptr) zip_source_free(source);
      zip_discard(archive);
      fail(why);
    }
  }
  if (zip_close(archive) != 0) {
    const std::string why = zip_strerror(archive);
    zip_discard(archive);
    fail(why);
  }
  std::error_code ec;
  std::filesystem::rename(tmp, file, ec);
  if (ec) fail("cannot rename " + tmp.string() + ": " + ec.message());
}

}  // namespace fracvi
