// The version of fracvi (`fracvi --version`, summary.json, problem.toml). Bottom layer.
#pragma once

#include <string>
#include <string_view>

namespace fracvi {

/// "0.1.0" (CMake's project version).
std::string_view version();
/// The git commit the build was configured from ("unknown" outside a git checkout). Recorded at
/// configure time: a build after new commits without re-running CMake keeps the older hash.
std::string_view git_commit();
/// "fracvi 0.1.0 (commit 1a2b3c4)".
std::string version_string();

}  // namespace fracvi
