#pragma once
// The hex transfinite (Gordon-Hall) interpolation as the textbook writes it,
// independent of tfi.hpp's factored form: the Boolean sum of the three
// axes' linear blends,
//   X = sum over faces (one axis fixed) - edges (two) + corners (three),
// each entity's value weighted by the product, over its fixed axes, of
// s_a (the high side) or 1 - s_a (the low side). Evaluated in long double;
// `magnitude` (the sum of every |value| used) sizes a rounding tolerance.
#include <array>
#include <cmath>

namespace dicer::test {

struct GordonHall {
  long double x = 0;
  long double magnitude = 0;
};

// at(side): the value at the entity point where side[a] is 0 (low end of
// axis a), 1 (high end) or 2 (free: the point's own coordinate on a).
template <class At>
GordonHall gordon_hall(const At& at, const std::array<double, 3>& s) {
  GordonHall r;
  for (int code = 0; code < 27; ++code) {
    const std::array<int, 3> side{code % 3, code / 3 % 3, code / 9};
    int fixed = 0;
    long double weight = 1;
    for (int a = 0; a < 3; ++a) {
      if (side[a] == 2) continue;
      ++fixed;
      weight *= side[a] ? static_cast<long double>(s[a]) : 1.0L - static_cast<long double>(s[a]);
    }
    if (fixed == 0) continue;  // the point itself
    const double v = at(side);
    r.x += (fixed == 2 ? -weight : weight) * static_cast<long double>(v);
    r.magnitude += std::fabs(static_cast<long double>(v));
  }
  return r;
}

}  // namespace dicer::test
