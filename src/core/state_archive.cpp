#include "fracvi/core/state_archive.hpp"

#include <cstdint>
#include <cstring>
#include <string>

namespace fracvi {

namespace {
constexpr char kDoubles = 'd';
constexpr char kCount = 'n';
}  // namespace

void StateArchive::expect(std::string_view name, std::size_t value) {
  std::size_t stored = value;
  count(name, stored);
  if (stored != value) {
    throw CheckpointError("checkpoint record '" + std::string(name) + "' = " +
                          std::to_string(stored) + " but this run has " + std::to_string(value) +
                          " (the checkpoint is of another problem, scheme or method option)");
  }
}

void StateArchive::flag(std::string_view name, bool& value) {
  std::size_t n = value ? 1 : 0;
  count(name, n);
  value = n != 0;
}

// Record: name length (u32), name, type (one byte), length (u64), payload.
void StateWriter::header(std::string_view name, char type, std::size_t length) {
  const auto name_length = static_cast<std::uint32_t>(name.size());
  const auto n = static_cast<std::uint64_t>(length);
  bytes_.append(reinterpret_cast<const char*>(&name_length), sizeof name_length);
  bytes_.append(name);
  bytes_.push_back(type);
  bytes_.append(reinterpret_cast<const char*>(&n), sizeof n);
}

void StateWriter::doubles(std::string_view name, std::span<double> values) {
  header(name, kDoubles, values.size());
  // An empty block (a fast block history without tail terms) may have no data pointer at all.
  if (!values.empty()) {
    bytes_.append(reinterpret_cast<const char*>(values.data()), values.size_bytes());
  }
}

void StateWriter::count(std::string_view name, std::size_t& value) {
  header(name, kCount, 1);
  const auto v = static_cast<std::uint64_t>(value);
  bytes_.append(reinterpret_cast<const char*>(&v), sizeof v);
}

void StateReader::fail(const std::string& what) const {
  throw CheckpointError(where_.empty() ? what : where_ + ": " + what);
}

void StateReader::read(void* out, std::size_t n, std::string_view name) {
  if (bytes_.size() - offset_ < n) {
    fail("truncated in record '" + std::string(name) + "' (corrupt or incomplete checkpoint)");
  }
  if (n == 0) return;  // `out` may be null (an empty block), which memcpy does not allow
  std::memcpy(out, bytes_.data() + offset_, n);
  offset_ += n;
}

std::size_t StateReader::header(std::string_view name, char type) {
  std::uint32_t name_length = 0;
  read(&name_length, sizeof name_length, name);
  if (name_length > 256 || bytes_.size() - offset_ < name_length) {
    fail("corrupt record header where '" + std::string(name) + "' was expected");
  }
  const std::string_view stored = bytes_.substr(offset_, name_length);
  offset_ += name_length;
  if (stored != name) {
    fail("record '" + std::string(stored) + "' where '" + std::string(name) +
         "' was expected (a checkpoint of another scheme or history, or corrupt)");
  }
  char stored_type = 0;
  read(&stored_type, 1, name);
  if (stored_type != type) fail("record '" + std::string(name) + "' has the wrong type");
  std::uint64_t length = 0;
  read(&length, sizeof length, name);
  return static_cast<std::size_t>(length);
}

void StateReader::doubles(std::string_view name, std::span<double> values) {
  const std::size_t length = header(name, kDoubles);
  if (length != values.size()) {
    fail("record '" + std::string(name) + "' has " + std::to_string(length) +
         " values, this run needs " + std::to_string(values.size()) +
         " (a checkpoint of another problem, or corrupt)");
  }
  read(values.data(), values.size_bytes(), name);
}

void StateReader::count(std::string_view name, std::size_t& value) {
  if (header(name, kCount) != 1) fail("record '" + std::string(name) + "' is corrupt");
  std::uint64_t v = 0;
  read(&v, sizeof v, name);
  value = static_cast<std::size_t>(v);
}

void StateReader::finish() const {
  if (offset_ != bytes_.size()) {
    fail(std::to_string(bytes_.size() - offset_) +
         " bytes of state left over after the last record this run restores (a checkpoint of "
         "another scheme, or corrupt)");
  }
}

}  // namespace fracvi
