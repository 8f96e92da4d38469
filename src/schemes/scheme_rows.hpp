// The registry rows, one per scheme file (internal; listed in registry.cpp).
#pragma once

#include "fracvi/schemes/registry.hpp"

namespace fracvi::internal {

extern const SchemeInfo kFviGl;        // fvi_gl.cpp
extern const SchemeInfo kFviBdf2;      // fvi_bdf2.cpp
extern const SchemeInfo kFviMidpoint;  // fvi_midpoint.cpp
extern const SchemeInfo kFviLobatto2;  // fvi_lobatto.cpp
extern const SchemeInfo kFviLobatto3;  // fvi_lobatto.cpp
extern const SchemeInfo kFviLobatto4;  // fvi_lobatto.cpp
// The baselines (docs/theory/baselines.md).
extern const SchemeInfo kEulerExplicit;    // euler.cpp
extern const SchemeInfo kEulerImplicit;    // euler.cpp
extern const SchemeInfo kLdaMidpoint;      // lda_midpoint.cpp
extern const SchemeInfo kConformalStrang;  // conformal_strang.cpp
extern const SchemeInfo kDopri5;           // dopri5.cpp
extern const SchemeInfo kPiTrapezoid;      // pi_trapezoid.cpp

}  // namespace fracvi::internal
