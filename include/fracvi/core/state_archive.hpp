// The state of a run as a checkpoint sees it (`[output] checkpoint_every`, `fracvi run --resume`).
//
// Every object that a run needs to continue bit-for-bit — the Integrator's rows and health
// checks, the Stepper's state, the damping History — has one function visit_state(StateArchive&)
// that names each number it keeps. The same function saves (StateWriter) and restores
// (StateReader) them, the idiom of Boost.Serialization's serialize(Archive&): the two directions
// cannot drift apart, and a field added to one is in the other.
//
// Records are named and typed; a reader checks every name, type and length against the object it
// restores, so a checkpoint of another problem or scheme, or a truncated or altered one, is a
// CheckpointError naming the record, never a silently different state. Doubles are stored as
// their IEEE 754 binary64 bytes (exact; the checkpoint header records the byte order).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>

namespace fracvi {

/// A checkpoint that cannot be written or restored: missing, corrupt, or not the state of this
/// problem and scheme. The message names the file or record and what was expected.
class CheckpointError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class StateArchive {
 public:
  virtual ~StateArchive() = default;

  /// True when restoring (values are read into the arguments), false when saving.
  [[nodiscard]] virtual bool loading() const = 0;
  /// A block of doubles, bit-exact. Restoring: the record must have this name and exactly
  /// values.size() entries.
  virtual void doubles(std::string_view name, std::span<double> values) = 0;
  /// A count or step index.
  virtual void count(std::string_view name, std::size_t& value) = 0;

  void number(std::string_view name, double& value) { doubles(name, {&value, 1}); }
  /// The whole of a dense Eigen vector or matrix (its size is the object's, fixed at construction).
  template <class Derived>
  void dense(std::string_view name, Eigen::DenseBase<Derived>& m) {
    doubles(name, {m.derived().data(), static_cast<std::size_t>(m.size())});
  }
  /// A structural size (a dimension, a capacity, a window) that the restored object must share
  /// with the saved one: written when saving, compared when restoring (CheckpointError when it
  /// differs).
  void expect(std::string_view name, std::size_t value);
  /// A flag, stored as a count 0/1.
  void flag(std::string_view name, bool& value);
  /// An optional part of the state (a damping memory that only damped runs have): whether it
  /// exists, checked against this run, then the part's own visit_state(*this).
  template <class Part>
  void optional(std::string_view name, Part* part) {
    bool present = part != nullptr;
    flag(name, present);
    if (present != (part != nullptr)) {
      throw CheckpointError("checkpoint record '" + std::string(name) +
                            "' does not match this run");
    }
    if (part != nullptr) part->visit_state(*this);
  }
};

/// Saves records into a byte string.
class StateWriter final : public StateArchive {
 public:
  [[nodiscard]] bool loading() const override { return false; }
  void doubles(std::string_view name, std::span<double> values) override;
  void count(std::string_view name, std::size_t& value) override;
  [[nodiscard]] const std::string& bytes() const { return bytes_; }

 private:
  void header(std::string_view name, char type, std::size_t length);
  std::string bytes_;
};

/// Restores records from a byte string written by StateWriter. `where` names the source in
/// messages (the checkpoint file; "" when the caller adds it).
class StateReader final : public StateArchive {
 public:
  StateReader(std::string_view bytes, std::string where)
      : bytes_(bytes), where_(std::move(where)) {}
  [[nodiscard]] bool loading() const override { return true; }
  void doubles(std::string_view name, std::span<double> values) override;
  void count(std::string_view name, std::size_t& value) override;
  /// Throws CheckpointError unless every record has been read (a checkpoint with more state than
  /// the object restored is another object's).
  void finish() const;

 private:
  // Reads the next record's header, checks its name and type, returns its length.
  std::size_t header(std::string_view name, char type);
  void read(void* out, std::size_t n, std::string_view name);
  [[noreturn]] void fail(const std::string& what) const;
  std::string_view bytes_;
  std::size_t offset_ = 0;
  std::string where_;
};

}  // namespace fracvi
