#pragma once
/// @file
/// The normal velocity a contact is to prescribe, as sim_core/collision/contact.h states the
/// rule, written out again for the colliders' tests to compare with: from inside the shell,
/// onto it within the step; from outside, the particle's own velocity relative to the
/// surface, unless that would carry it past the shell within the step, when onto it.

namespace costume::test {

/// `gap` [m] from the shell (< 0 inside), `relative` the particle's normal velocity relative
/// to the surface [m/s], `surface` the surface's normal velocity [m/s], step `h` [s].
inline double ExpectedContactVelocity(double surface, double gap, double relative, double h) {
  const double onto_shell = surface - gap / h;
  if (gap <= 0.0) return onto_shell;
  const bool would_cross = gap + h * relative < 0.0;
  return would_cross ? onto_shell : surface + relative;
}

}  // namespace costume::test
