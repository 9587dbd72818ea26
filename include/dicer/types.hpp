#pragma once
// Basic value types shared by every stage.
#include <array>
#include <cstdint>

namespace dicer {

// All ids (coarse and fine) are 64-bit: a 10^10-element mesh overflows 32 bits.
using Id = std::int64_t;

struct Vec3 {
  double x = 0, y = 0, z = 0;
  friend bool operator==(const Vec3&, const Vec3&) = default;
};
// Coordinate d (0: x, 1: y, 2: z) of p.
inline double component(const Vec3& p, int d) { return d == 0 ? p.x : d == 1 ? p.y : p.z; }

// Volume mode dices hexahedra; surface mode dices quadrilaterals.
enum class Mode : std::uint8_t { Volume = 3, Surface = 2 };

inline const char* mode_name(Mode m) { return m == Mode::Volume ? "volume" : "surface"; }

}  // namespace dicer
