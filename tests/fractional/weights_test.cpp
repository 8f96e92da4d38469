#include "fracvi/fractional/weights.hpp"
#include <gtest/gtest.h>
TEST(GlWeights, FirstValues) {
  auto w = fracvi::gl_weights(0.5, 3);
  EXPECT_DOUBLE_EQ(w[1], -0.5);
}
