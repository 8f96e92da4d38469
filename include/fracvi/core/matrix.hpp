// Storage types shared by every layer: states are row-major (one row per stored step), so that a
// trajectory can be handed to NumPy without a copy.
#pragma once

#include <Eigen/Core>

namespace fracvi {

using RowMatrixXd = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

}  // namespace fracvi
