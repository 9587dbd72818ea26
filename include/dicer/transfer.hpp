#pragma once
// Transfer: the operators between two nested dicings of one coarse mesh,
// kept as implicit as the meshes themselves (geometric multigrid).
//
// Nesting. Two stores of the same coarse mesh are nested when every sheet's
// interval in the fine store is a multiple m >= 1 of its interval in the
// coarse store (a coarse store diced at interval 1 is the coarse mesh
// itself). "The same coarse mesh" is checked on content, never on names:
// mode, counts, every element's corner vertices, edges, faces, orientation
// flags, block and file id, every corner coordinate bit for bit, every
// edge's ends, sheet and owner, every face's corners, sides and owner, and
// every geometric owner (the same CAD) must agree; anything else, a
// reordered copy of the same mesh included, is a different mesh.
//
// Prolongation P (rows: fine-store node ids, columns: coarse-store node
// ids, both in id order). Fine node (I, J, K) of coarse element h (its
// element-local grid, as its owner sees it) lies, per axis a with factor
// m_a = fine n_a / coarse n_a, in coarse-store cell c = I / m_a at
// t = (I mod m_a) / m_a (at I = n_a: c = coarse n_a - 1, t = 1). Its row
// holds the Q1 (Q1 on quads) shape-function weights at t of that cell's
// 8 (4) corner nodes, exact zeros dropped, in corner order dz, dy, dx
// (slowest first). Each weight is one correctly rounded quotient of exact
// integers, prod_a (m_a - r_a or r_a) / prod_a m_a, so a row is the same in
// every frame its node can be seen from, its weights lie in [0, 1] and sum
// to 1 up to rounding, and a fine node that coincides with a coarse one
// (r_a = 0 on every axis) has a unit row. No point location: the position
// is the numbering's.
//
// Coincident nodes are bit-identical between nested stores (TFI weights
// double(m t) / double(m n) are the same correctly rounded quotients as
// double(t) / double(n); nodes moved onto the CAD are stored losslessly),
// so P's unit rows pick exactly the coarse node's coordinates. Nodes moved
// onto a CAD are identical when both stores were diced with the same CAD:
// the conformer chooses each entity's placement from probes at fixed
// parameters, not from its interval (geometry.hpp). check_nesting still
// compares every moved coarse-store node with its fine-store twin and
// reports the first that differs (Nesting::moved_nodes_differ): stores
// written by a dicer before that choice can differ there.
//
// Cost. check_nesting and the constructor read every coarse table row of
// both stores once (O(coarse mesh)). P is never formed: rows are generated
// a coarse element at a time, its owned boundary in one batch, its
// interior a slab of grid planes at a time (at most kCursorSlabPoints
// rows of at most 8 entries), in id order. A generator holds one slab and
// both grids' boundary ids of one element (O(fine n^2), as a BatchCursor
// does); apply_transpose adds one element's boundary of partial sums
// (O(coarse n^2)) per thread; a thread's contributions to
// coarse nodes owned by earlier threads are kept, one per coarse element
// and node (O(the boundary of its range)), and added after the join in
// thread order, so P^T y is bit-identical for every thread count, and
// under MPI for every rank count (mpi.hpp prolong/restrict_to).
// Thread safety: const members may be called concurrently; one
// ProlongationCursor per thread.
// Errors: stores of different coarse meshes, of different modes, or not
// nested: Error{BadInput} naming both files and the first difference; a
// row that contradicts the nesting: Error{Corrupt}; spans of the wrong
// size or ranges outside the mesh: Error{Usage}.
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "dicer/fine_mesh.hpp"

namespace dicer {

struct Nesting {
  bool nested = false;
  Id sheets = 0;
  // The first sheet (ids as `dicer sheets` prints them) whose fine interval
  // is not a multiple of its coarse one: -1 when nested.
  Id sheet = -1, coarse_interval = 0, fine_interval = 0;
  // Set (with `sheet`, the first graded one) when a sheet is graded in
  // either store: P's weights assume equal spacing, so it is refused.
  bool graded = false;
  Id min_factor = 0, max_factor = 0;  // over sheets, fine / coarse (nested only)
  Id rows = 0, cols = 0;              // P's shape: fine nodes x coarse nodes
  // Nodes moved onto the CAD in the coarse store whose fine-store twin has
  // other bits (0 when both were diced with the same CAD), and the first.
  Id moved_nodes_checked = 0, moved_nodes_differ = 0, first_differing_coarse_node = -1;
  std::string message;                // one line, for people
};

// The content check, then the per-sheet test. Throws Error{BadInput} when
// the two are not dicings of one coarse mesh (naming both and the first
// difference); a non-nested pair is a return value.
Nesting check_nesting(const FineMesh& coarse, const FineMesh& fine);

// A batch of consecutive rows of P in CSR form: rows [row_begin, row_end)
// (fine node ids), row r's entries at [offsets[r - row_begin],
// offsets[r - row_begin + 1]) of cols (coarse node ids) and weights;
// offsets[0] = 0. Valid until the cursor's next call.
struct ProlongationBatch {
  Id coarse_element = -1;
  Id row_begin = 0, row_end = 0;
  std::span<const Id> offsets, cols;
  std::span<const double> weights;
  Id num_rows() const { return row_end - row_begin; }
  Id num_entries() const { return offsets.empty() ? 0 : offsets.back(); }
};

class Prolongation;
namespace detail {
class RowGenerator;
}

// The rows of the fine nodes owned by coarse elements [first, end), in
// increasing id order, a batch at a time: per coarse element its owned
// boundary nodes (one batch), then its interior about `slab_rows` rows
// per batch (whole grid planes). Over [0, H) every row of P exactly once.
class ProlongationCursor {
 public:
  ProlongationCursor(const Prolongation& p, Id first = 0, Id end = -1, Id slab_rows = kCursorSlabPoints);
  ~ProlongationCursor();
  ProlongationCursor(const ProlongationCursor&) = delete;
  ProlongationCursor& operator=(const ProlongationCursor&) = delete;
  bool next(ProlongationBatch& out);

 private:
  std::unique_ptr<detail::RowGenerator> gen_;
};

class Prolongation {
 public:
  // check_nesting, refusing a pair that is not nested (Error{BadInput}
  // naming the sheet). Both meshes must outlive the operator.
  Prolongation(const FineMesh& coarse, const FineMesh& fine);

  const FineMesh& coarse() const { return coarse_; }
  const FineMesh& fine() const { return fine_; }
  const Nesting& nesting() const { return nesting_; }
  Id rows() const { return fine_.num_nodes(); }
  Id cols() const { return coarse_.num_nodes(); }
  int max_row_entries() const { return fine_.mode() == Mode::Volume ? 8 : 4; }
  // Non-zeros of P, counted from the tables (O(coarse mesh), no row made):
  // per axis a fine node has 1 entry where it sits on a coarse grid plane,
  // else 2; an entity of n fine intervals over n_c coarse ones has
  // 2n - n_c - 1 entries along it over its n - 1 interior nodes.
  Id nonzeros() const { return nonzeros_; }

  // y = P x (x: cols() values, y: rows() values), `threads` threads over
  // coarse element ranges; the same bits for every thread count.
  void apply(std::span<const double> x, std::span<double> y, unsigned threads = 1) const;
  // x = P^T y (y: rows() values; x: cols() values, overwritten); the same
  // bits for every thread count (see the top of this file).
  void apply_transpose(std::span<const double> y, std::span<double> x, unsigned threads = 1) const;

  // ---- Per range of coarse elements (an MPI rank's chunk, a thread).
  // The rows coarse elements [first, end) own (fine node ids) and the
  // columns they own (coarse node ids): one id range each (owner order).
  std::array<Id, 2> owned_rows(Id first, Id end) const;
  std::array<Id, 2> owned_cols(Id first, Id end) const;
  // Columns the rows of [first, end) may read that earlier elements own:
  // the coarse-store nodes of the elements' entities owned before `first`,
  // sorted (a superset of what the rows read; the coarse store's ghosts of
  // that chunk, partition.hpp). O(boundary of the range).
  std::vector<Id> ghost_cols(Id first, Id end) const;
  // y_owned = the rows of [first, end) times x, where x_local holds the
  // owned columns (owned_cols order) followed by `ghosts` (ghost_cols) in
  // that order.
  void apply_range(Id first, Id end, std::span<const Id> ghosts, std::span<const double> x_local,
                   std::span<double> y_owned) const;
  // The transpose of the rows of [first, end) applied to y_owned: added
  // into x_owned (the owned columns; the caller zeroes it first), and the
  // contributions to columns owned before `first` appended to `lower` as
  // (column, value), one per coarse element and column, in element order.
  // Adding every range's `lower` entries, ranges in order and each in its
  // order, after the ranges' own sums gives the single range's bits.
  void apply_transpose_range(Id first, Id end, std::span<const double> y_owned, std::span<double> x_owned,
                             std::vector<std::pair<Id, double>>& lower) const;

 private:
  const FineMesh& coarse_;
  const FineMesh& fine_;
  Nesting nesting_;
  Id nonzeros_ = 0;
  friend class detail::RowGenerator;
};

// ---- Assembled P, streamed to a file (library dicer_export). Each writes
// through AtomicOutput (nothing under `path` until complete), generating
// the rows once, in id order, a batch at a time: memory is one batch plus
// the write buffers, whatever the size of P. progress(rows done, rows) is
// called between batches; an exception it throws (a cancel) ends the
// write and removes the temporary.
//
// CSR in HDF5, readable by h5py + scipy (csr_matrix((data, indices,
// indptr), shape)): datasets indptr [rows + 1] int64, indices [nnz] int64,
// data [nnz] float64, chunked, shuffled and deflated (HDF5's built-in
// filters only); root attributes shape = [rows, cols] (int64), nnz, format
// = "csr", coarse and fine (the stores' paths and uuids), columns (what
// they number: `columns_are`, by default "coarse store node ids"). Error{Io}.
//
// columns (both writers): the column written for coarse node c is
// columns[c], a permutation of 0 .. cols-1 (each row's entries stay
// ascending); empty: c itself. `dicer transfer MESHFILE FINE` numbers
// them by the mesh file's node ids (cli/cmd_transfer.cpp). Error{Usage}
// for a columns span that is not such a permutation.
void write_prolongation_hdf5(const Prolongation& p, const std::string& path,
                             const std::function<void(Id, Id)>& progress = {}, std::span<const Id> columns = {},
                             const std::string& columns_are = {});
// PETSc's binary matrix format (what MatLoad reads, MATAIJ): big-endian
// int header [1211216 (MAT_FILE_CLASSID), rows, cols, nnz], rows row
// lengths, nnz column indices, then nnz float64 values. Ints are int32
// (index_bytes 4, PETSc's default build) or int64 (8, PETSc built
// --with-64-bit-indices); a count that does not fit int32 is Error{Usage}
// naming it. The three sections are written at their offsets as the rows
// stream (nnz is known from the tables beforehand). Error{Io}.
void write_prolongation_petsc(const Prolongation& p, const std::string& path, int index_bytes = 4,
                              const std::function<void(Id, Id)>& progress = {}, std::span<const Id> columns = {});

}  // namespace dicer
