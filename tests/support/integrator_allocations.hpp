// allocations_while_stepping: the heap allocations of an Integrator's step loop. Includes
// allocation_counter.hpp, which interposes malloc: include either header in exactly ONE
// translation unit of a test executable (allocation_test, the scheme suite).
#pragma once

#include <gtest/gtest.h>

#include <cstddef>

#include "allocation_counter.hpp"
#include "fracvi/integrate/integrator.hpp"

namespace fracvi::test {

/// Allocations counted while stepping `integ` to the end (construction is not counted); the run
/// must succeed.
inline std::size_t allocations_while_stepping(Integrator& integ) {
  g_allocations = 0;
  g_counting = true;
  Status s = Status::kRunning;
  while (s == Status::kRunning) s = integ.step();
  g_counting = false;
  EXPECT_EQ(s, Status::kSuccess);
  return g_allocations;
}

}  // namespace fracvi::test
