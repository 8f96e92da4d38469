// Checkpoints of `fracvi run` (`[output] checkpoint_every = n`) and `fracvi run --resume DIR`.
//
// A checkpoint is one file, DIR/checkpoint.fracvi, beside the run's problem.toml:
//
//   FRACVI-CHECKPOINT 1\n
//   {"byte_order": "little", "fracvi_version": …, "scheme": …, "step": k, "steps": N,
//    "state_bytes": n, "state_fnv1a64": "…", "problem": "<the resolved problem.toml>"}\n
//   <n bytes: the Integrator's state (Integrator::visit_state, core/state_archive.hpp)>
//
// The state holds everything the run needs to continue bit-for-bit after step k: the stored rows
// 0, s, 2s, … ≤ k (t, x, v, energy, dissipated work, balance), the statistics and the running
// quantities of the health checks, and the stepper's state — x_k, p_k, the damping force, the
// energy account, Newton's predictor and the damping memory (the direct history's values, or the
// fast history's window and exponential recursions). Resuming rebuilds the Integrator from the
// problem (which recomputes the weights and the fast history's fit), restores that state and runs
// on; the rows of the checkpoint and those computed after it make the trajectory, written once at
// the end like any run's. The file is written atomically (a temporary, then a rename), so an
// interrupted or killed run leaves the previous checkpoint or the new one, never half of one.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>

#include "fracvi/core/state_archive.hpp"
#include "fracvi/integrate/integrator.hpp"
#include "fracvi/io/problem_file.hpp"

namespace fracvi {

/// The checkpoint's file name inside the output directory.
inline constexpr const char* kCheckpointFile = "checkpoint.fracvi";

/// Writes DIR/problem.toml and DIR/checkpoint.fracvi with the state of `integrator` after its
/// current step (atomically, under the directory's OutputLock). Throws CheckpointError when the
/// state cannot be saved (the scheme has no checkpoints, the run is not running) and OutputError
/// when the files cannot be written.
void write_checkpoint(const std::filesystem::path& dir, const ProblemSpec& spec,
                      Integrator& integrator);

/// A checkpoint read back and checked: its header, its checksum, and the problem it was taken
/// with.
struct Checkpoint {
  ProblemSpec spec;      ///< DIR/problem.toml, identical to the problem of the checkpoint
  std::size_t step = 0;  ///< the last completed step k
  std::string scheme;    ///< method.scheme
  std::string state;     ///< the Integrator's state (StateReader input)
  std::filesystem::path file;
};

/// Reads DIR/checkpoint.fracvi and DIR/problem.toml. Throws CheckpointError "<file>: <what>" when
/// either is missing, the checkpoint is corrupt (format, header, size or checksum), or the problem
/// in DIR differs from the one the checkpoint was taken with (naming the first differing line);
/// ProblemFileError when problem.toml itself is invalid.
Checkpoint read_checkpoint(const std::filesystem::path& dir);

/// Restores `integrator` (constructed from checkpoint.spec's problem, method and options) to the
/// checkpoint's state. Throws CheckpointError when the state does not fit the integrator (which
/// is then unusable: it may be partly restored).
void restore_checkpoint(const Checkpoint& checkpoint, Integrator& integrator);

}  // namespace fracvi
