#include "dicer/sweep.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <exception>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "dicer/batch.hpp"
#include "dicer/error.hpp"
#include "dicer/orientation.hpp"
#include "dicer/rows.hpp"
#include "clones.hpp"
#include "work_split.hpp"

namespace dicer {
namespace {

// sweep.hpp's mix: xorshift, odd multiply, xorshift, each a bijection; one
// multiply instead of murmur3's two (0.4).
constexpr std::uint64_t kMixMultiplier = 0xd6e8feb86659fd93ull;
inline std::uint64_t mix(std::uint64_t h) {
  h ^= h >> 32;
  h *= kMixMultiplier;
  h ^= h >> 32;
  return h;
}

constexpr const std::uint64_t* K = kChecksumKeys;

// A node's term from its id's product id K0.
inline std::uint64_t node_term_of_product(std::uint64_t idk, std::uint64_t x, std::uint64_t y, std::uint64_t z) {
  return mix(idk ^ x ^ std::rotl(y, 21) ^ std::rotl(z, 42));
}
inline std::uint64_t node_term(std::uint64_t id, std::uint64_t x, std::uint64_t y, std::uint64_t z) {
  return node_term_of_product(id * K[0], x, y, z);
}

// mix's argument for an element: id K4 + node[0] K5 + ...
template <int C>
inline std::uint64_t element_arg(std::uint64_t id, const Id* nodes) {
  std::uint64_t h = id * K[4];
  for (int q = 0; q < C; ++q) h += static_cast<std::uint64_t>(nodes[q]) * K[5 + q];
  return h;
}
template <int C>
inline std::uint64_t element_term(std::uint64_t id, const Id* nodes) {
  return mix(element_arg<C>(id, nodes));
}

// The loops over a batch: independent terms, no branch, so the compiler
// vectorises them (clones.hpp; integer arithmetic, so every clone gives the
// same sum).
// The ids' products advance by K0 per node: an add where AVX2 has no
// 64-bit multiply.
DICER_WIDE_CLONES std::uint64_t sum_nodes(std::uint64_t first, const double* x, const double* y, const double* z,
                                          std::int64_t n) {
  std::uint64_t sum = 0, idk = first * K[0];
  for (std::int64_t i = 0; i < n; ++i, idk += K[0]) {
    std::uint64_t bx, by, bz;
    std::memcpy(&bx, x + i, 8), std::memcpy(&by, y + i, 8), std::memcpy(&bz, z + i, 8);
    sum += node_term_of_product(idk, bx, by, bz);
  }
  return sum;
}

template <int C>
inline std::uint64_t sum_elements(std::uint64_t first, const Id* conn, std::int64_t n) {
  std::uint64_t sum = 0;
  for (std::int64_t e = 0; e < n; ++e) sum += element_term<C>(first + static_cast<std::uint64_t>(e), conn + C * e);
  return sum;
}
// Clones cannot be templates (Clang): one function per corner count.
DICER_WIDE_CLONES std::uint64_t sum_hexes(std::uint64_t first, const Id* conn, std::int64_t n) {
  return sum_elements<8>(first, conn, n);
}
DICER_WIDE_CLONES std::uint64_t sum_quads(std::uint64_t first, const Id* conn, std::int64_t n) {
  return sum_elements<4>(first, conn, n);
}

// Hex terms of the m elements of one row, each in full, their corners
// read from the grid rows around it (grid_cell_corner): contiguous loads,
// no connectivity formed.
DICER_WIDE_CLONES std::uint64_t sum_hex_row(std::uint64_t first, const Id* const* rows, std::int64_t m) {
  const Id* const r[4] = {rows[0], rows[1], rows[2], rows[3]};  // held in registers
  std::uint64_t sum = 0;
  for (std::int64_t i = 0; i < m; ++i) {
    Id nodes[8];
    for (int q = 0; q < 8; ++q) nodes[q] = grid_cell_corner(r, i, q);
    sum += element_term<8>(first + static_cast<std::uint64_t>(i), nodes);
  }
  return sum;
}

// The keys of the corners read from each of a cell's four grid rows
// (grid_cell_row) at the cell's own i (A) and at i + 1 (B), and both
// summed: a row's step times its sum is what its corners add to the step
// of a progression of arguments (products distribute mod 2^64).
struct RowKeys {
  std::array<std::uint64_t, 4> a{}, b{}, ab{};
};
constexpr RowKeys kRowKeys = [] {
  RowKeys k;
  for (int q = 0; q < 8; ++q) {
    const int r = grid_cell_row(q);
    (kHexCorner[q][0] == 0 ? k.a : k.b)[r] += kChecksumKeys[5 + q];
    k.ab[r] += kChecksumKeys[5 + q];
  }
  return k;
}();

// Whether any grid row bends inside its interior: the OR over points g of
// (p[g + 1] - p[g]) ^ (p[g + 2] - p[g + 1]) where inner[g] (all ones where g
// is a row's point t, 1 <= t <= n0 - 3: steps inside the interior), over
// the whole grid at once (one long vector loop, no store). A batch's grid
// never bends (batch.hpp), so rows are checked one by one only when some
// row does.
DICER_WIDE_CLONES std::uint64_t bends(const std::uint64_t* p, Id count, const std::uint64_t* inner) {
  std::uint64_t any = 0;
  for (Id g = 0; g + 2 < count; ++g) any |= ((p[g + 1] - p[g]) ^ (p[g + 2] - p[g + 1])) & inner[g];
  return any;
}

// Each grid row q = grid + r (n0 + 1) as a line through its interior
// q[1 .. n0 - 1]: first = q[1], step = q[2] - q[1], ok = the interior is
// that progression (mod 2^64, the arithmetic of the terms: any step, no
// overflow on any input; a cell's interior rows step by 1, a face's by 1,
// -1 or a row of the face's canonical grid, an edge's by 1 or -1), and
// how far the end points lie off the line: off0 = q[0] - (q[1] - step),
// offn = q[n0] - (q[n0 - 1] + step). n0 >= 3. Only where some row bends
// (bends()); straight_lines below otherwise.
struct GridLines {
  std::uint64_t *first, *step, *off0, *offn;
  std::uint8_t* ok;
};
// Every row's line (no ok): one plain loop over the rows, strided loads.
// Alone where no row bends (a batch's grid, or bends() found none): the
// loop with the bend check was 6% of a sweep at interval 10 (121 rows per
// coarse hex).
DICER_WIDE_CLONES void straight_lines(const std::uint64_t* p, Id rows, Id n0, std::uint64_t* __restrict first,
                                      std::uint64_t* __restrict step, std::uint64_t* __restrict off0,
                                      std::uint64_t* __restrict offn) {
  const Id ni = n0 + 1;
  for (Id r = 0; r < rows; ++r) {
    const std::uint64_t* q = p + r * ni;
    const std::uint64_t a = q[1], s = q[2] - a;
    first[r] = a, step[r] = s, off0[r] = q[0] - a + s, offn[r] = q[n0] - q[n0 - 1] - s;
  }
}
void grid_lines(const std::uint64_t* p, Id rows, Id n0, const GridLines& L) {
  straight_lines(p, rows, n0, L.first, L.step, L.off0, L.offn);
  const Id ni = n0 + 1;
  for (Id r = 0; r < rows; ++r) {
    const std::uint64_t* q = p + r * ni;
    std::uint64_t off = 0;
    for (Id t = 2; t < n0 - 1; ++t) off |= (q[t + 1] - q[t]) ^ L.step[r];
    L.ok[r] = off == 0;
  }
}

// Element rows as lines through their argument progressions, from the
// grid rows' lines: where the four grid rows that element row reads (r,
// r + 1 in its layer, r + w, r + w + 1 in the next; w = n1 + 1) are
// progressions, element i's argument (id K4 + the sum of corner id x key)
// is a1 + (i - 1) step for 1 <= i <= n0 - 2, and the two end elements
// differ from the line only by their end points' offsets times the keys of
// the corners that read them. base + idk[r]: the id part of the row's
// element 1.
// Every r < count, also those that are no element row (j = n1): one
// unit-stride vector loop over the whole grid.
DICER_WIDE_CLONES void element_lines(const GridLines& L, std::uint64_t base, const std::uint64_t* idk, Id count, Id w, Id n0,
                                     std::uint64_t* __restrict a0, std::uint64_t* __restrict a1,
                                     std::uint64_t* __restrict step, std::uint64_t* __restrict an) {
  const std::uint64_t* first[4] = {L.first, L.first + 1, L.first + w, L.first + w + 1};
  const std::uint64_t* st[4] = {L.step, L.step + 1, L.step + w, L.step + w + 1};
  const std::uint64_t* o0[4] = {L.off0, L.off0 + 1, L.off0 + w, L.off0 + w + 1};
  const std::uint64_t* on[4] = {L.offn, L.offn + 1, L.offn + w, L.offn + w + 1};
  const auto m2 = static_cast<std::uint64_t>(n0 - 2);
  for (Id r = 0; r < count; ++r) {
    std::uint64_t s = K[4], h = base + idk[r], e0 = 0, en = 0;
    for (int q = 0; q < 4; ++q) {
      s += kRowKeys.ab[q] * st[q][r];
      h += kRowKeys.ab[q] * first[q][r] + kRowKeys.b[q] * st[q][r];
      e0 += kRowKeys.a[q] * o0[q][r];
      en += kRowKeys.b[q] * on[q][r];
    }
    a1[r] = h, step[r] = s, a0[r] = h - s + e0, an[r] = h + m2 * s + en;
  }
}

// The rows' terms: mix(a0), mix(a1 + t step) for t < n0 - 2, mix(an),
// summed over the rows r < count (a multiple of kLanes) whose keep[r] is
// all ones. Rows side by side, kLanes at a time: one vector lane per row,
// so a short row (n0 = 10: eight terms on its line) fills the vector as
// a long one does.
// Written with GCC's vector types (Clang has them too), not as a loop
// over lanes for the vectoriser: GCC 12.2 at -O3 vectorised that loop
// wrongly for AVX2 (wrong sums on every machine without AVX-512, the
// clone they run; test_sweep's GridChecksum test caught it under
// valgrind, whose CPU has no AVX-512). A vector type is lowered to the
// widest the clone has (one zmm, two ymm, four xmm), with no vectoriser
// decision left to get wrong.
constexpr Id kLanes = 8;
typedef std::uint64_t U64xLanes __attribute__((vector_size(8 * kLanes)));
// By reference: a vector passed or returned by value between a clone and
// a function built for baseline x86-64 would change the calling
// convention (an unoptimised build does not inline, and crashed).
inline void mix_lanes(U64xLanes& h) {
  h ^= h >> 32;
  h *= kMixMultiplier;
  h ^= h >> 32;
}
DICER_WIDE_CLONES std::uint64_t hash_lines(const std::uint64_t* a0, const std::uint64_t* a1,
                                           const std::uint64_t* step, const std::uint64_t* an,
                                           const std::uint64_t* keep, Id count, Id n0) {
  U64xLanes total = {}, s, h, m, part, k;
  for (Id r0 = 0; r0 < count; r0 += kLanes) {
    std::memcpy(&s, step + r0, sizeof s), std::memcpy(&h, a1 + r0, sizeof h);
    std::memcpy(&part, a0 + r0, sizeof part), std::memcpy(&m, an + r0, sizeof m);
    mix_lanes(part), mix_lanes(m);
    part += m;
    for (Id t = 0; t < n0 - 2; ++t) {
      m = h;
      mix_lanes(m);
      part += m, h += s;
    }
    std::memcpy(&k, keep + r0, sizeof k);
    total += part & k;
  }
  std::uint64_t sum = 0;
  for (Id b = 0; b < kLanes; ++b) sum += total[b];
  return sum;
}

// The grid rows' lines and the element rows' work space of one batch, warm
// after the first: no allocation per batch. Rows r < er: every element
// row's r (and the j = n1 between layers), padded to whole vectors with
// rows kept out; the grid rows' lines padded too (element_lines reads up
// to row ep + w).
// a0, a1, step and an have 2 kLanes rows of room past ep (continue_layers
// runs on past the last layer); run: continue_layers' running values.
struct LineSpace {
  GridLines L;
  std::uint64_t *a0, *a1, *step, *an, *idk, *keep, *run;
  size_t er, ep;
};
LineSpace line_space(Id grid_rows, Id w, Id layers) {
  const size_t gr = static_cast<size_t>(grid_rows), er = static_cast<size_t>(w * layers - 1);
  const size_t ep = (er + kLanes - 1) / kLanes * kLanes, gp = gr + kLanes, ap = ep + 2 * kLanes;
  const size_t run = 2 * static_cast<size_t>((w + kLanes - 1) / kLanes * kLanes);
  thread_local std::vector<std::uint64_t> space;
  thread_local std::vector<std::uint8_t> oks;
  space.resize(4 * gp + 4 * ap + 2 * ep + run), oks.resize(gr);
  std::uint64_t* const ws = space.data();
  LineSpace S{{ws, ws + gp, ws + 2 * gp, ws + 3 * gp, oks.data()}, nullptr, nullptr, nullptr, nullptr, nullptr,
              nullptr, nullptr, er, ep};
  S.a0 = ws + 4 * gp, S.a1 = S.a0 + ap, S.step = S.a1 + ap, S.an = S.step + ap, S.idk = S.an + ap,
  S.keep = S.idk + ep, S.run = S.keep + ep;
  std::fill(S.idk + er, S.idk + ep, 0), std::fill(S.keep + er, S.keep + ep, 0);
  return S;
}

// Of a batch's shape alone: element row r = j + (n1 + 1) k's element 1
// less the batch's first element, times K4 (idk), and which rows are
// element rows (keep: not j = n1 between layers, nor the padding past er).
// Formed once per shape: a sweep's batches mostly share one (formed per
// batch, they were 2.8% of a sweep at interval 10).
struct RowIds {
  Id n0 = -1, n1 = -1, layers = -1;
  std::vector<std::uint64_t> idk, keep;
};
const RowIds& row_ids(Id n0, Id n1, Id layers, size_t ep) {
  thread_local RowIds c;
  if (c.n0 != n0 || c.n1 != n1 || c.layers != layers) {
    c.n0 = -1;  // a throw below leaves no shape to reuse
    c.idk.assign(ep, 0), c.keep.assign(ep, 0);
    const Id w = n1 + 1;
    for (Id k = 0; k < layers; ++k)
      for (Id j = 0; j < n1; ++j) {
        const auto r = static_cast<size_t>(j + w * k);
        c.idk[r] = static_cast<std::uint64_t>(j + n1 * k) * static_cast<std::uint64_t>(n0) * K[4];
        c.keep[r] = ~std::uint64_t{0};
      }
    c.n0 = n0, c.n1 = n1, c.layers = layers;
  }
  return c;
}

// Layers l = from .. to - 1 of each of a0, a1, step and an (rows r = j +
// w l, j < w) continued from the two before them: x(l) = x(from - 1) +
// (l - from + 1) d with d = x(from - 1) - x(from - 2), exact (mod 2^64)
// where the rows are affine in the layer (straight_rows_checksum). A
// layer at a time in whole vectors of kLanes rows, each running on into
// the next layer by up to kLanes - 1 rows (which the next layer, or the
// rows formed after, overwrite; the arrays have that much room past ep):
// the running values stay in `run`, so nothing is loaded back that was
// just stored (loads straddling earlier vector stores missed store
// forwarding, and a loop reading x[r - w] cost more than the
// element_lines it replaced).
DICER_WIDE_CLONES void continue_layers(std::uint64_t* const* x, Id w, Id from, Id to, std::uint64_t* run) {
  const Id chunks = (w + kLanes - 1) / kLanes;
  std::uint64_t* const d = run + kLanes * chunks;  // then the steps
  for (int a = 0; a < 4; ++a) {
    std::uint64_t* const v = x[a];
    for (Id c = 0; c < chunks; ++c) {
      U64xLanes x0, x1;
      std::memcpy(&x0, v + w * (from - 2) + kLanes * c, sizeof x0);
      std::memcpy(&x1, v + w * (from - 1) + kLanes * c, sizeof x1);
      x0 = x1 - x0;
      std::memcpy(run + kLanes * c, &x1, sizeof x1), std::memcpy(d + kLanes * c, &x0, sizeof x0);
    }
    for (Id l = from; l < to; ++l)
      for (Id c = 0; c < chunks; ++c) {
        U64xLanes cur, step;
        std::memcpy(&cur, run + kLanes * c, sizeof cur), std::memcpy(&step, d + kLanes * c, sizeof step);
        cur += step;
        std::memcpy(run + kLanes * c, &cur, sizeof cur), std::memcpy(v + w * l + kLanes * c, &cur, sizeof cur);
      }
  }
}

// The hex terms of `layers` layers of n0 x n1 elements, ids from `id` on,
// whose grid rows all are the lines in S.L (none bends): element rows as
// lines (element_lines), hashed side by side (hash_lines).
// Layers [la, lb] (lb - la >= 2) may be known affine: each of their
// element rows' a0, a1, step and an a function a + b l of the layer l at
// fixed j. Those past la + 1 are then continued from the two before them
// (continue_layers), not formed from the grid rows: element_lines, 16
// 64-bit multiplies a row, was 9% of a sweep at interval 10.
std::uint64_t straight_rows_checksum(const LineSpace& S, std::uint64_t id, Id n0, Id n1, Id layers, Id la = 0,
                                     Id lb = -1) {
  const RowIds& rows = row_ids(n0, n1, layers, S.ep);
  const auto ep = static_cast<Id>(S.ep);
  const Id w = n1 + 1;
  const std::uint64_t base = (id + 1) * K[4];
  auto form = [&](Id r0, Id r1) {  // element rows [r0, r1) from the grid rows' lines
    r1 = std::min(r1, ep);
    if (r0 >= r1) return;
    const GridLines& L = S.L;
    const GridLines at{L.first + r0, L.step + r0, L.off0 + r0, L.offn + r0, nullptr};
    element_lines(at, base, rows.idk.data() + r0, r1 - r0, w, n0, S.a0 + r0, S.a1 + r0, S.step + r0, S.an + r0);
  };
  if (lb - la >= 2) {
    form(0, w * (la + 2));
    std::uint64_t* const x[4] = {S.a0, S.a1, S.step, S.an};
    continue_layers(x, w, la + 2, lb + 1, S.run);
    form(w * (lb + 1), ep);
#ifndef NDEBUG
    thread_local std::vector<std::uint64_t> full;
    full.resize(4 * S.ep);
    std::uint64_t* const f = full.data();
    element_lines(S.L, base, rows.idk.data(), ep, w, n0, f, f + ep, f + 2 * ep, f + 3 * ep);
    for (Id r = 0; r < ep; ++r)
      if (rows.keep[static_cast<size_t>(r)])
        for (int a = 0; a < 4; ++a)
          DICER_ASSERT(f[a * ep + r] == x[a][r], "sweep: element rows continued across layers not affine");
#endif
  } else {
    form(0, ep);
  }
  return hash_lines(S.a0, S.a1, S.step, S.an, rows.keep.data(), ep, n0);
}

// checksum_hex_grid; lines: the grid rows' interiors are known to be
// progressions (a batch's grid: batch.hpp), so they are checked only in
// debug builds (a check that cost 7-12% of a sweep).
std::uint64_t grid_checksum(Id first, const std::array<Id, 3>& n, Id layers, std::span<const Id> grid, bool lines) {
  // Sizes checked in 128 bits: no overflow on any input.
  const __int128 want = static_cast<__int128>(n[0] + __int128{1}) * (n[1] + __int128{1}) * (layers + __int128{1});
  if (n[0] < 1 || n[1] < 1 || layers < 0 || want != static_cast<__int128>(grid.size()))
    throw Error(ErrorKind::Usage, "checksum_hex_grid: a grid of " + std::to_string(grid.size()) +
                                      " ids for " + std::to_string(layers) + " layers of " + std::to_string(n[0]) +
                                      " x " + std::to_string(n[1]));
  const Id ni = n[0] + 1, n0 = n[0], n1 = n[1], w = n1 + 1;
  const Id grid_rows = w * (layers + 1);
  auto id = static_cast<std::uint64_t>(first);
  const auto row_rows = [&](Id ra) {  // the four grid rows element row ra reads
    const Id* g = grid.data();
    return std::array<const Id*, 4>{g + ra * ni, g + (ra + 1) * ni, g + (ra + w) * ni, g + (ra + w + 1) * ni};
  };
  // Rows of fewer than two interior points (no line to follow): each term
  // in full.
  if (n0 < 3 || layers == 0) {
    std::uint64_t sum = 0;
    for (Id k = 0; k < layers; ++k)
      for (Id j = 0; j < n1; ++j, id += static_cast<std::uint64_t>(n0))
        sum += sum_hex_row(id, row_rows(j + w * k).data(), n0);
    return sum;
  }
  const LineSpace S = line_space(grid_rows, w, layers);
  const GridLines& L = S.L;
  const size_t er = S.er;
  // Signed and unsigned variants of one type may alias.
  const auto* p = reinterpret_cast<const std::uint64_t*>(grid.data());
#ifdef NDEBUG
  const bool check = !lines;
#else
  const bool check = true;
#endif
  bool bent = false;
  if (check) {
    // bends()'s mask: periodic in the row length, so kept for the longest
    // grid of that row length yet (a sweep's batches mostly share one).
    const auto points = static_cast<Id>(grid.size());
    thread_local std::vector<std::uint64_t> inner;
    thread_local Id inner_ni = 0;
    if (inner_ni != ni || static_cast<Id>(inner.size()) < points) {
      inner.resize(std::max(static_cast<size_t>(points), inner_ni == ni ? inner.size() : 0));
      for (size_t g = 0; g < inner.size(); ++g) {
        const auto t = static_cast<Id>(g % static_cast<size_t>(ni));
        inner[g] = t >= 1 && t <= n0 - 3 ? ~std::uint64_t{0} : 0;
      }
      inner_ni = ni;
    }
    bent = bends(p, points, inner.data()) != 0;
    DICER_ASSERT(!lines || !bent, "checksum of a batch's grid: a grid row's interior is no progression (batch.hpp)");
  }
  if (!bent) {  // every element row a line
    straight_lines(p, grid_rows, n0, L.first, L.step, L.off0, L.offn);
    return straight_rows_checksum(S, id, n0, n1, layers);
  }
  // Which rows the lines hash; the others' terms in full.
  std::uint64_t sum = 0;
  grid_lines(p, grid_rows, n0, L);
  for (Id k = 0; k < layers; ++k)
    for (Id j = 0; j <= n1 && j + w * k < static_cast<Id>(er); ++j) {
      const Id r = j + w * k;
      S.idk[r] = (id + 1) * K[4];  // element 1 of the row
      const bool line = j < n1 && (L.ok[r] & L.ok[r + 1] & L.ok[r + w] & L.ok[r + w + 1]);
      S.keep[r] = line ? ~std::uint64_t{0} : 0;
      if (j == n1) continue;
      if (!line) sum += sum_hex_row(id, row_rows(r).data(), n0);
      id += static_cast<std::uint64_t>(n0);
    }
  element_lines(L, 0, S.idk, static_cast<Id>(S.ep), w, n0, S.a0, S.a1, S.step, S.an);
  return sum + hash_lines(S.a0, S.a1, S.step, S.an, S.keep, static_cast<Id>(S.ep), n0);
}

// The lines of a batch (FineBatch::lines) as straight_lines would find them
// in its grid: off0 = start - (first - step), offn = end - (first + (n0 - 1) step).
DICER_WIDE_CLONES void batch_lines(const std::uint64_t* start, const std::uint64_t* first, const std::uint64_t* step,
                                   const std::uint64_t* end, Id rows, Id n0, std::uint64_t* __restrict f,
                                   std::uint64_t* __restrict s, std::uint64_t* __restrict off0,
                                   std::uint64_t* __restrict offn) {
  const auto m = static_cast<std::uint64_t>(n0 - 1);
  for (Id r = 0; r < rows; ++r) {
    const std::uint64_t a = first[r], st = step[r];
    f[r] = a, s[r] = st, off0[r] = start[r] - a + st, offn[r] = end[r] - a - m * st;
  }
}

// A batch's hex terms from its lines, the same sum as grid_checksum over
// the grid they describe. Its element layers first_layer + l with 1 <=
// first_layer + l <= n[2] - 2 read grid planes inside the hex only, whose
// rows each lie on one entity (the cell, a side face, a side edge) the
// same way on every such plane: their ids, so the lines and the element
// rows formed from them, are affine in l (numbering.hpp: an entity's ids
// are affine in its grid point).
std::uint64_t lines_checksum(Id first, const std::array<Id, 3>& n, Id first_layer, Id layers,
                             const FineBatch::Lines& lines) {
  const Id n0 = n[0], n1 = n[1], w = n1 + 1, rows = w * (layers + 1);
  DICER_ASSERT(static_cast<Id>(lines.start.size()) == rows && lines.first.size() == lines.start.size() &&
                   lines.step.size() == lines.start.size() && lines.end.size() == lines.start.size(),
               "sweep: a batch's lines, one per grid row");
  if (n0 < 3 || layers == 0) {  // short rows: their few points in full, as grid_checksum takes them
    thread_local std::vector<Id> grid;
    grid.resize(static_cast<size_t>(rows * (n0 + 1)));
    for (Id r = 0; r < rows; ++r) {
      Id* const q = grid.data() + r * (n0 + 1);
      q[0] = lines.start[r], q[n0] = lines.end[r];
      for (Id i = 1; i < n0; ++i) q[i] = lines.first[r] + (i - 1) * lines.step[r];
    }
    return grid_checksum(first, n, layers, grid, true);
  }
  const LineSpace S = line_space(rows, w, layers);
  const auto u = [](std::span<const Id> v) { return reinterpret_cast<const std::uint64_t*>(v.data()); };
  batch_lines(u(lines.start), u(lines.first), u(lines.step), u(lines.end), rows, n0, S.L.first, S.L.step, S.L.off0,
              S.L.offn);
  const Id la = std::max<Id>(0, 1 - first_layer), lb = std::min(layers - 1, n[2] - 2 - first_layer);
  return straight_rows_checksum(S, static_cast<std::uint64_t>(first), n0, n1, layers, la, lb);
}

}  // namespace

std::uint64_t checksum_hex_grid(Id first, const std::array<Id, 3>& n, Id layers, std::span<const Id> grid) {
  return grid_checksum(first, n, layers, grid, false);
}

std::uint64_t node_checksum_term(Id id, const Vec3& x) {
  return node_term(static_cast<std::uint64_t>(id), std::bit_cast<std::uint64_t>(x.x), std::bit_cast<std::uint64_t>(x.y),
                   std::bit_cast<std::uint64_t>(x.z));
}

std::uint64_t element_checksum_term(const FineElement& e) {
  return e.num_nodes == 8 ? element_term<8>(static_cast<std::uint64_t>(e.id), e.nodes.data())
                          : element_term<4>(static_cast<std::uint64_t>(e.id), e.nodes.data());
}

std::uint64_t checksum_nodes(Id first, std::span<const double> x, std::span<const double> y,
                             std::span<const double> z) {
  DICER_ASSERT(x.size() == y.size() && x.size() == z.size(), "checksum_nodes: x, y, z of one length");
  return sum_nodes(static_cast<std::uint64_t>(first), x.data(), y.data(), z.data(), static_cast<std::int64_t>(x.size()));
}

std::uint64_t checksum_elements(Id first, int corners, std::span<const Id> conn) {
  DICER_ASSERT(corners == 8 || corners == 4, "checksum_elements: 8 or 4 corners");
  const auto n = static_cast<std::int64_t>(conn.size()) / corners;
  return corners == 8 ? sum_hexes(static_cast<std::uint64_t>(first), conn.data(), n)
                      : sum_quads(static_cast<std::uint64_t>(first), conn.data(), n);
}

namespace detail {

std::vector<Id> split_work(const FineMesh& mesh, unsigned parts, Id first, Id end) {
  const MeshTables& t = mesh.tables();
  const Id H = mesh.num_coarse_elements();
  const __int128 all = static_cast<__int128>(mesh.num_nodes()) + mesh.num_elements();
  MeshCursor cur;
  const RowReader R(t, cur);
  // A store's work before element h is read off its page index: the first
  // ids of h's page and of the next, h's share of the page in between (the
  // rows of a page own about equal work; a split only needs balance). A
  // row read per probe loaded the pages one at a time before any thread
  // started: 5 of the 50 ms of a 16,000-hex sweep on 2 threads. The
  // threads load them anyway, in parallel.
  const Id rpp = t.elements.rows_per_page();
  const auto pages = static_cast<Id>(t.node_index.size());
  const bool indexed = rpp > 0 && pages == t.elements.pages() && t.element_index.size() == t.node_index.size();
  auto work_before = [&](Id h) -> __int128 {
    if (h >= H) return all;
    if (!indexed) return static_cast<__int128>(R.node_first(h)) + R.element_first(h);
    const Id p = h / rpp, r0 = p * rpp, r1 = std::min(H, r0 + rpp);
    const auto q = static_cast<size_t>(p);
    const __int128 a = static_cast<__int128>(t.node_index[q]) + t.element_index[q];
    const __int128 b = p + 1 < pages ? static_cast<__int128>(t.node_index[q + 1]) + t.element_index[q + 1] : all;
    return a + (b - a) * (h - r0) / (r1 - r0);
  };
  const __int128 w0 = work_before(first), total = work_before(end) - w0;
  std::vector<Id> at(parts + 1, end);
  at[0] = first;
  for (unsigned p = 1; p < parts; ++p) {
    const __int128 want = w0 + total * p / parts;
    Id lo = at[p - 1], hi = end;  // first element whose work before it is >= want
    while (lo < hi) {
      const Id mid = lo + (hi - lo) / 2;
      if (work_before(mid) < want) lo = mid + 1;
      else hi = mid;
    }
    at[p] = lo;
  }
  return at;
}

unsigned threads_for_cache(const FineMesh& mesh, unsigned threads) {
  threads = std::max(1u, threads);
  if (const auto& cache = mesh.tables().cache) {
    const std::uint64_t per_thread = 2ull * kSweepPagesPerThread * kStorePageBytes;
    threads = static_cast<unsigned>(std::clamp<std::uint64_t>(cache->budget() / per_thread, 1, threads));
  }
  return threads;
}

}  // namespace detail

SweepResult sweep(const FineMesh& mesh, unsigned threads, const std::function<void(Id, Id)>& progress, Id first_coarse,
                  Id end_coarse) {
  const Id H = mesh.num_coarse_elements();
  if (end_coarse < 0) end_coarse = H;
  if (first_coarse < 0 || first_coarse > end_coarse || end_coarse > H)
    throw Error(ErrorKind::Usage, "sweep: coarse elements " + std::to_string(first_coarse) + ".." +
                                      std::to_string(end_coarse) + " outside the mesh");
  threads = detail::threads_for_cache(mesh, threads);
  const auto start = std::chrono::steady_clock::now();
  Id nn = 0, ne = 0;
  {
    MeshCursor cur;
    const RowReader R(mesh.tables(), cur);
    const auto own = mesh.owned_nodes(first_coarse, end_coarse, cur);
    nn = own[1] - own[0];
    auto efirst = [&](Id h) { return h < H ? R.element_first(h) : mesh.num_elements(); };
    ne = efirst(end_coarse) - efirst(first_coarse);
  }
  const Id total = nn + ne;
  // Chunks of about equal work, taken by whichever thread is free: a static
  // split of one range per thread left the whole sweep waiting on its
  // slowest core (16 cores: bench/README.md, thread scaling).
  const unsigned chunks = threads == 1 ? 1 : threads * kSweepChunksPerThread;
  const std::vector<Id> split = detail::split_work(mesh, chunks, first_coarse, end_coarse);
  std::atomic<unsigned> next_chunk{0};
  std::atomic<Id> done{0};
  std::vector<std::uint64_t> sums(threads, 0);
  std::vector<std::exception_ptr> errors(threads);
  // Coarse elements in store order, a batch (slab) at a time: each chunk a
  // contiguous run, so a page of the store is read about once per sweep.
  auto work = [&](unsigned t) {
    try {
      std::uint64_t sum = 0;
      Id local = 0;
      // Hexes from the slab's grid rows as lines (no grid or connectivity
      // formed), quads from conn.
      BatchOptions opt;
      opt.lines = mesh.mode() == Mode::Volume;
      opt.conn = !opt.lines;
      std::optional<BatchCursor> batches;
      FineBatch b;
      for (unsigned c = next_chunk++; c < chunks; c = next_chunk++) {
        if (batches) batches->reset(split[c], split[c + 1]);
        else batches.emplace(mesh, split[c], split[c + 1], opt);
        while (batches->next(b)) {
          sum += checksum_nodes(b.node_begin, b.x, b.y, b.z);
          sum += opt.lines ? lines_checksum(b.element_begin, b.n, b.first_layer, b.num_elements() / (b.n[0] * b.n[1]),
                                            b.lines)
                           : checksum_elements(b.element_begin, b.corners, b.conn);
          local += b.num_nodes() + b.num_elements();
          if (local >= 65536) done += local, local = 0;
        }
      }
      done += local;
      sums[t] = sum;
    } catch (...) {
      errors[t] = std::current_exception();
      next_chunk = chunks;  // the others stop after their current chunk
    }
  };
  // Workers count themselves out, so the progress loop wakes the moment the
  // last one ends (a fixed sleep added up to 100 ms to every sweep) and
  // never waits on work that an exception cut short.
  std::mutex m;
  std::condition_variable cv;
  unsigned finished = 0;
  auto run = [&](unsigned t) {
    work(t);
    {
      std::lock_guard lock(m);
      ++finished;
    }
    cv.notify_one();
  };
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < threads; ++t) pool.emplace_back(run, t);
  if (progress) {
    pool.emplace_back(run, 0u);
    std::unique_lock lock(m);
    while (!cv.wait_for(lock, std::chrono::milliseconds(100), [&] { return finished == threads; })) {
      lock.unlock();
      progress(std::min(done.load(), total), total);
      lock.lock();
    }
  } else {
    run(0);
  }
  for (auto& th : pool) th.join();
  for (auto& e : errors)
    if (e) std::rethrow_exception(e);
  SweepResult r;
  r.threads = threads;
  r.nodes = nn, r.elements = ne;
  for (auto s : sums) r.checksum += s;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (progress) progress(total, total);
  return r;
}

}  // namespace dicer
