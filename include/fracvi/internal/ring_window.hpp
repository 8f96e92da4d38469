// The window of a ring buffer that holds each value once (internal; FastHistory and
// FastBlockHistory, memory/).
#pragma once

#include <Eigen/Core>

namespace fracvi::internal {

/// The column holding the window's value q (0 = the oldest) in a ring of `width` columns of
/// stride `ld` whose window starts at column `first` < width and wraps around the ring's end
/// (q < width). One comparison instead of a division: the kernels call it per group of four
/// columns, and the small systems' per value.
inline const double* ring_window_column(const double* ring, Eigen::Index ld, Eigen::Index width,
                                        Eigen::Index first, Eigen::Index q) {
  Eigen::Index column = first + q;
  if (column >= width) column -= width;
  return ring + column * ld;
}

}  // namespace fracvi::internal
