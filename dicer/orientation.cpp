// Canonical orientation (see include/dicer/orientation.hpp): the only file
// that turns local corner orders into canonical ones.
#include "dicer/orientation.hpp"

#include "dicer/error.hpp"

namespace dicer {

FaceCode compose(FaceCode a, FaceCode b) {
  for (int c = 0; c < 8; ++c) {
    bool ok = true;
    for (int m = 0; m < 4 && ok; ++m)
      ok = code_corner(static_cast<FaceCode>(c), m) == code_corner(a, code_corner(b, m));
    if (ok) return static_cast<FaceCode>(c);
  }
  DICER_ASSERT(false, "the square's symmetries are closed under composition");
}

FaceCode inverse(FaceCode a) {
  for (int c = 0; c < 8; ++c)
    if (compose(static_cast<FaceCode>(c), a) == 0) return static_cast<FaceCode>(c);
  DICER_ASSERT(false, "every symmetry of the square has an inverse");
}

CanonicalQuad canonical_quad(const std::array<Id, 4>& h) {
  int r = 0;
  for (int m = 1; m < 4; ++m)
    if (h[m] < h[r]) r = m;
  const int s = h[(r + 1) % 4] < h[(r + 3) % 4] ? 1 : -1;
  CanonicalQuad q{};
  for (int m = 0; m < 4; ++m) q.v[m] = h[((r + s * m) % 4 + 4) % 4];
  // Local corner m is canonical corner k with r + s*k == m, i.e. k = s*(m - r).
  q.code = make_code((s == 1 ? -r : r) & 3, s == -1);
  return q;
}

}  // namespace dicer
