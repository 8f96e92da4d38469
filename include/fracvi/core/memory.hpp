// Memory estimates checked before a run allocates: a problem that cannot fit is refused with the
// number instead of dying in std::bad_alloc (or the OOM killer) after minutes of set-up.
#pragma once

#include <cstddef>
#include <string>

namespace fracvi {

/// The machine's physical memory in bytes (sysconf); 0 when unknown (then nothing is refused).
std::size_t physical_memory_bytes();

/// "1.6 GB", "104 GB", "512 kB": bytes in decimal units, 3 significant digits.
std::string format_bytes(double bytes);

/// Throws ValidationError "<what> needs <bytes>, more than this machine's memory (<total>)<advice>"
/// when `bytes` exceeds the physical memory.
void check_fits_in_memory(double bytes, const std::string& what, const std::string& advice);

}  // namespace fracvi
