// dicer._core: the library's store, queries, chunks and partitions for
// Python. The Python package (python/dicer/__init__.py) adds argument
// checks worded like the CLI's, `dice --geometry` through dicer-cad, and
// Chunk.to_meshio.
//
// Every call reaches the library through the same functions the dicer
// command uses (read_store, NodeCursor, ElementCursor, ExportChunk,
// sweep), so Python gets the CLI's bits. Long calls run without the GIL.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <sys/stat.h>

#include <algorithm>
#include <map>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <tuple>
#include <vector>

#include "arrays.hpp"
#include "dicer/coarse_mesh.hpp"
#include "dicer/diced_rows.hpp"
#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/intervals.hpp"
#include "dicer/locate.hpp"
#include "dicer/neighbors.hpp"
#include "dicer/mpi.hpp"
#include "dicer/partition.hpp"
#include "dicer/quadratic.hpp"
#include "dicer/store.hpp"
#include "dicer/sweep.hpp"
#include "dicer/batch.hpp"
#include "dicer/transfer.hpp"
#include "dicer/version.hpp"
#include "errors.hpp"

namespace dicer::py_module {
namespace {

using Mesh = std::shared_ptr<const FineMesh>;

// ---- Store

struct Store {
  Mesh mesh;
  std::string path;  // as given (repr, messages)
  // What info, chunk() and partition() read again (the sets, the file's
  // size): the file opened, by absolute path, checked to be the same file
  // (os.chdir, or a store written over it since, must not change answers).
  std::string file;
  dev_t dev = 0;
  ino_t ino = 0;
  StoreOptions options;
  std::vector<std::string> warnings, notes;  // from dice(): the mesh reader's warnings, interval conflicts

  // A copy, held for the length of a call, so close() from another thread
  // cannot pull the mesh from under it.
  Mesh get() const {
    if (!mesh) throw Error(ErrorKind::Usage, path + ": the store is closed");
    return mesh;
  }
  // The opened file's path, after checking it is still that file.
  const std::string& reread() const {
    struct stat st {};
    if (::stat(file.c_str(), &st) != 0 || st.st_dev != dev || st.st_ino != ino)
      throw Error(ErrorKind::Io, path + ": the file was removed or replaced since the store was opened; open it again");
    return file;
  }
};

// The CLI's --cache-mb and --read-ahead limits and words (messages name
// the command-line option of each argument, as every message here does).
void check_open_options(std::int64_t cache_mb, std::int64_t read_ahead) {
  if (cache_mb < 1 || cache_mb > (std::int64_t{1} << 30))
    throw Error(ErrorKind::Usage, "--cache-mb: must be between 1 and 2^30 (MiB)");
  if (read_ahead < 0 || read_ahead > 1024) throw Error(ErrorKind::Usage, "--read-ahead: must be between 0 and 1024 pages");
}

Store open_store(const std::string& path, std::int64_t cache_mb, std::int64_t read_ahead, bool keep_tables) {
  check_open_options(cache_mb, read_ahead);
  Store s;
  s.path = path;
  s.file = std::filesystem::absolute(path).string();
  s.options.cache_bytes = static_cast<std::uint64_t>(cache_mb) << 20;
  s.options.read_ahead_pages = static_cast<unsigned>(read_ahead);
  s.options.keep_coarse_tables = keep_tables;
  ReleaseGil release;
  // Read by the absolute name (a later os.chdir must not lose the file);
  // messages name it as given, the words `dicer` prints.
  try {
    FineMesh m = read_store(s.file, s.options);
    m.set_origin(path);
    s.mesh = std::make_shared<const FineMesh>(std::move(m));
  } catch (const Error& e) {
    const std::string what = e.what();
    if (what.rfind(s.file, 0) != 0) throw;
    throw Error(e.kind(), path + what.substr(s.file.size()));
  }
  // The identity of the file read (a replacement in between is caught by
  // the sets' uuid check, read_store_sets).
  struct stat st {};
  if (::stat(s.file.c_str(), &st) == 0) s.dev = st.st_dev, s.ino = st.st_ino;
  return s;
}

// The keys and order of `dicer info --json` (cli/cmd_info.cpp).
py::dict info_dict(const Store& s) {
  const Mesh m = s.get();
  const StoreSummary sum = [&] {
    ReleaseGil release;
    return store_summary(s.reread());
  }();
  const MeshInfo& c = m->info();
  py::list blocks;
  for (size_t b = 0; b < c.blocks.size(); ++b) {
    py::dict d;
    d["id"] = c.blocks[b].id;
    d["name"] = text(c.blocks[b].name);
    d["coarse_elements"] = c.block_coarse_elements[b];
    d["fine_elements"] = c.block_fine_elements[b];
    blocks.append(d);
  }
  py::dict d;
  d["mode"] = mode_name(m->mode());
  d["source"] = path_text(c.source);
  d["source_order"] = c.source_order;
  if (c.geometry.empty()) d["geometry"] = py::none();
  else d["geometry"] = path_text(c.geometry);
  d["format_version"] = sum.format_version;
  d["store_bytes"] = sum.file_bytes;
  d["coarse_vertices"] = c.coarse_vertices;
  d["coarse_edges"] = c.coarse_edges;
  d["coarse_faces"] = c.coarse_faces;
  d["coarse_elements"] = c.coarse_elements;
  d["sheets"] = c.sheets;
  d["sheet_intervals"] = m->sheet_intervals();
  py::list gradings;  // None, or {kind, ratio, start}: cli/json_out.hpp grading_json
  for (const SheetGrading& g : m->sheet_gradings()) {
    if (g.grading.kind == tfi::Spacing::Equal) {
      gradings.append(py::none());
      continue;
    }
    py::dict q;
    q["kind"] = g.grading.kind == tfi::Spacing::Dual ? "dual" : "geometric";
    q["ratio"] = g.grading.ratio;
    if (g.grading.kind == tfi::Spacing::Geometric) q["start"] = g.start;
    gradings.append(q);
  }
  d["sheet_gradings"] = gradings;
  d["fine_nodes"] = m->num_nodes();
  d["fine_elements"] = m->num_elements();
  d["blocks"] = blocks;
  return d;
}

py::dict cache_stats(const Store& s) {
  const Mesh m = s.get();
  const auto cache = store_cache(*m);
  const CacheStats st = cache->stats();
  py::dict d;
  d["budget_bytes"] = cache->budget();
  d["pages_read"] = st.pages_read;
  d["distinct_pages_read"] = st.distinct_pages_read;
  d["bytes_read"] = st.bytes_read;
  d["bytes_decompressed"] = st.bytes_decompressed;
  d["hits"] = st.hits;
  d["misses"] = st.misses;
  d["evictions"] = st.evictions;
  d["resident_bytes"] = st.resident_bytes;
  d["peak_resident_bytes"] = st.peak_resident_bytes;
  d["kept_bytes"] = st.kept_bytes;
  d["load_seconds"] = static_cast<double>(st.load_ns) * 1e-9;
  d["demand_load_seconds"] = static_cast<double>(st.demand_load_ns) * 1e-9;
  d["load_wait_seconds"] = static_cast<double>(st.load_wait_ns) * 1e-9;
  return d;
}

// Ids given either as (start, stop) or as one sequence of ids.
struct IdSelection {
  bool range = true;
  Id a = 0, b = 0;
  std::vector<Id> ids;
  size_t size() const { return range ? static_cast<size_t>(b - a) : ids.size(); }
};

// A value as a message quotes it, at most 60 characters (dicer._quoted):
// str() of an int past Python's digit limit (4300) raises, and so may a
// user's __str__.
std::string quoted(const py::handle& v) {
  try {
    std::string text = py::str(v);
    // Counted in characters, as _quoted: a UTF-8 sequence is never split.
    const auto after = [&](size_t chars) {
      size_t at = 0;
      for (size_t c = 0; c < chars && at < text.size(); ++c)
        do ++at;
        while (at < text.size() && (static_cast<unsigned char>(text[at]) & 0xC0) == 0x80);
      return at;
    };
    if (after(61) < text.size()) text = text.substr(0, after(57)) + "...";
    return "\"" + text + "\"";
  } catch (const py::error_already_set&) {
  }
  try {
    if (PyLong_Check(v.ptr())) return "an integer of " + std::string(py::str(v.attr("bit_length")())) + " bits";
    return "a " + std::string(py::str(py::type::handle_of(v).attr("__name__")));
  } catch (const py::error_already_set&) {
    return "a value";
  }
}

// Python's bool and numpy's (numpy.bool_, numpy.bool in numpy 2): both
// have __index__, and an id of True is a mistake, not 1.
bool is_bool(const py::handle& v) {
  if (PyBool_Check(v.ptr())) return true;
  const py::handle t = py::type::handle_of(v);
  if (!py::hasattr(t, "__module__") || std::string(py::str(t.attr("__module__"))) != "numpy") return false;
  const std::string name = py::str(t.attr("__name__"));
  return name == "bool_" || name == "bool";
}

// A Python int or numpy integer (anything with __index__ but a bool, as
// dicer._whole): an id. Beyond 64 bits: IdOverflowError, as _whole.
Id whole_id(const py::object& v, const std::string& what) {
  const auto not_whole = [&] { return Error(ErrorKind::Usage, what + ": " + quoted(v) + " is not a whole number"); };
  if (is_bool(v) || !py::hasattr(v, "__index__")) throw not_whole();
  py::object i;
  try {
    i = v.attr("__index__")();
  } catch (const py::error_already_set&) {
    throw not_whole();
  }
  if (!PyLong_Check(i.ptr())) throw not_whole();
  int overflow = 0;
  const long long out = PyLong_AsLongLongAndOverflow(i.ptr(), &overflow);
  if (overflow != 0) throw Error(ErrorKind::Overflow, what + ": " + quoted(v) + " does not fit in 64 bits");
  if (out == -1 && PyErr_Occurred()) throw py::error_already_set();
  return out;
}

// True or False (Python's or numpy's bool) for a switch: connectivity=None
// or "no" is the caller's mistake, not False.
bool switch_value(const py::object& v, const std::string& what) {
  if (!is_bool(v)) throw Error(ErrorKind::Usage, what + ": must be True or False, not " + quoted(v));
  return PyObject_IsTrue(v.ptr()) == 1;
}

// A number (int or float, not a bool or a string); finite: as the command
// reads --max-distance.
double number_value(const py::handle& v, const std::string& what, bool finite) {
  const auto bad = [&] {
    return Error(ErrorKind::Usage, what + ": " + quoted(v) + (finite ? " is not a finite number" : " is not a number"));
  };
  if (is_bool(v) || py::isinstance<py::str>(v) || py::isinstance<py::bytes>(v)) throw bad();
  const double d = PyFloat_AsDouble(v.ptr());
  if (d == -1.0 && PyErr_Occurred()) {
    PyErr_Clear();  // not a number, or an int past a double's range
    throw bad();
  }
  if (finite && !std::isfinite(d)) throw bad();
  return d;
}

double finite_value(const py::object& v, const std::string& what) { return number_value(v, what, true); }

// Three numbers (a sequence or array of 3), for a box corner.
std::array<double, 3> three_numbers(const py::object& v, const std::string& what) {
  if (py::isinstance<py::str>(v) || py::isinstance<py::bytes>(v) || !py::hasattr(v, "__len__") ||
      !py::hasattr(v, "__getitem__") || py::len(v) != 3)
    throw Error(ErrorKind::Usage, what + ": " + quoted(v) + " is not 3 numbers");
  std::array<double, 3> out{};
  for (size_t a = 0; a < 3; ++a) out[a] = number_value(v[py::int_(a)], what, false);
  return out;
}

IdSelection select_ids(const char* what, const py::object& first, const py::object& stop, const FineMesh& mesh) {
  IdSelection sel;
  const std::string plural = std::string(what) + "s";
  if (!stop.is_none()) {
    sel.a = whole_id(first, plural + "(start, stop): start");
    sel.b = whole_id(stop, plural + "(start, stop): stop");
    if (sel.b < sel.a) throw Error(ErrorKind::Usage, plural + "(start, stop): stop is below start");
    // The CLI's words for `query --nodes a:b` out of range.
    if (std::string(what) == "node") mesh.check_node_range(sel.a, sel.b);
    else mesh.check_element_range(sel.a, sel.b);
    return sel;
  }
  sel.range = false;
  py::module_ np = py::module_::import("numpy");
  py::array arr = np.attr("asarray")(first);
  if (arr.ndim() != 1)
    throw Error(ErrorKind::Usage, plural + "(ids): ids must be a 1-d sequence of whole numbers (or give start, stop)");
  const char k = arr.dtype().kind();
  if (arr.size() > 0 && k != 'i' && k != 'u')
    throw Error(ErrorKind::Usage, plural + "(ids): ids must be whole numbers, not " + std::string(py::str(arr.dtype())));
  // Unsigned ids above 2^63 - 1 would wrap to negative ones in int64.
  if (arr.size() > 0 && k == 'u' && arr.dtype().itemsize() == 8) {
    const py::object top = arr.attr("max")();
    if (top.cast<std::uint64_t>() > static_cast<std::uint64_t>(std::numeric_limits<Id>::max()))
      throw Error(ErrorKind::Usage, std::string(what) + " id " + std::string(py::str(top)) + " is out of range (the mesh has " +
                                        std::to_string(std::string(what) == "node" ? mesh.num_nodes() : mesh.num_elements()) +
                                        " " + plural + ")");
  }
  auto ids = np.attr("ascontiguousarray")(arr, py::arg("dtype") = "int64").cast<py::array_t<std::int64_t>>();
  sel.ids.assign(ids.data(), ids.data() + ids.size());
  return sel;
}

// Ids per call of FineMesh::nodes / elements for nodes(ids) and
// elements(ids): their work space stays bounded (under 30 MiB) whatever
// the number of ids.
constexpr size_t kIdsPerCall = size_t{1} << 18;

py::array nodes(const Store& s, const py::object& first, const py::object& stop) {
  const Mesh m = s.get();
  const IdSelection sel = select_ids("node", first, stop, *m);
  std::vector<double> xyz(3 * sel.size());
  {
    ReleaseGil release;
    if (sel.range) {
      // The cursor `dicer query --nodes` uses: one pass in id order.
      NodeCursor cur(*m, sel.a, sel.b);
      Id id;
      Vec3 p;
      for (size_t i = 0; cur.next(id, p); ++i) xyz[3 * i] = p.x, xyz[3 * i + 1] = p.y, xyz[3 * i + 2] = p.z;
    } else {
      // FineMesh::nodes, a bounded piece at a time: each piece visits its
      // ids in order, sharing every coarse element's search and row.
      MeshCursor cur;
      std::vector<Vec3> piece(std::min(sel.ids.size(), kIdsPerCall));
      for (size_t i0 = 0; i0 < sel.ids.size(); i0 += piece.size()) {
        const size_t n = std::min(piece.size(), sel.ids.size() - i0);
        m->nodes(std::span<const Id>(sel.ids).subspan(i0, n), std::span<Vec3>(piece).first(n), cur);
        for (size_t i = 0; i < n; ++i) {
          const Vec3& p = piece[i];
          xyz[3 * (i0 + i)] = p.x, xyz[3 * (i0 + i) + 1] = p.y, xyz[3 * (i0 + i) + 2] = p.z;
        }
      }
    }
  }
  return owned(std::move(xyz), {static_cast<py::ssize_t>(sel.size()), 3});
}

// What `dicer query --elements --json` prints, as arrays (`details`: the
// block, coarse element and ijk columns too).
struct ElementRows {
  Mesh mesh;
  py::ssize_t count = 0;
  std::vector<Id> nodes, block, coarse, ijk;
};

ElementRows element_rows(const Store& s, const py::object& first, const py::object& stop, bool details) {
  ElementRows r;
  r.mesh = s.get();
  const FineMesh& m = *r.mesh;
  const IdSelection sel = select_ids("element", first, stop, m);
  r.count = static_cast<py::ssize_t>(sel.size());
  ReleaseGil release;
  const int corners = m.corners(), dims = m.mode() == Mode::Volume ? 3 : 2;
  r.nodes.resize(sel.size() * static_cast<size_t>(corners));
  if (details) {
    r.block.resize(sel.size());
    r.coarse.resize(sel.size());
    r.ijk.resize(sel.size() * static_cast<size_t>(dims));
  }
  auto put = [&](size_t i, const FineElement& e) {
    std::copy_n(e.nodes.begin(), corners, r.nodes.begin() + static_cast<std::ptrdiff_t>(i) * corners);
    if (!details) return;
    r.block[i] = m.info().blocks.at(static_cast<size_t>(e.block)).id;
    r.coarse[i] = e.coarse_element;
    std::copy_n(e.ijk.begin(), dims, r.ijk.begin() + static_cast<std::ptrdiff_t>(i) * dims);
  };
  FineElement e;
  if (sel.range) {
    ElementCursor cur(m, sel.a, sel.b);
    for (size_t i = 0; cur.next(e); ++i) put(i, e);
  } else {
    MeshCursor cur;
    std::vector<FineElement> piece(std::min(sel.ids.size(), kIdsPerCall));
    for (size_t i0 = 0; i0 < sel.ids.size(); i0 += piece.size()) {
      const size_t n = std::min(piece.size(), sel.ids.size() - i0);
      m.elements(std::span<const Id>(sel.ids).subspan(i0, n), std::span<FineElement>(piece).first(n), cur);
      for (size_t i = 0; i < n; ++i) put(i0 + i, piece[i]);
    }
  }
  return r;
}

py::array elements(const Store& s, const py::object& first, const py::object& stop) {
  ElementRows r = element_rows(s, first, stop, false);
  return owned(std::move(r.nodes), {r.count, r.mesh->corners()});
}

py::dict element_info(const Store& s, const py::object& first, const py::object& stop) {
  ElementRows r = element_rows(s, first, stop, true);
  py::dict d;
  d["nodes"] = owned(std::move(r.nodes), {r.count, r.mesh->corners()});
  d["block"] = owned(std::move(r.block));
  d["coarse_element"] = owned(std::move(r.coarse));
  d["ijk"] = owned(std::move(r.ijk), {r.count, r.mesh->mode() == Mode::Volume ? 3 : 2});
  return d;
}

py::array elements_in_box(const Store& s, const py::object& lo, const py::object& hi) {
  const Mesh m = s.get();
  Box box;
  const auto a = three_numbers(lo, "elements_in_box: lo"), b = three_numbers(hi, "elements_in_box: hi");
  std::copy(a.begin(), a.end(), box.lo.begin());
  std::copy(b.begin(), b.end(), box.hi.begin());
  check_box(box, "elements_in_box");
  std::vector<Id> ids;
  {
    ReleaseGil release;
    for_each_in_box(*m, box, [&](const FineBlock& b, Id e) { ids.push_back(b.first_element + e); });
  }
  return owned(std::move(ids));
}

// Point location (locate.hpp), as `dicer query --points`: volume stores
// give (element ids, xi (n, 3)), surface stores (element ids, xi (n, 2),
// distances).
py::tuple locate(const Store& s, const py::array_t<double, py::array::c_style | py::array::forcecast>& points,
                 std::int64_t threads, const std::optional<double>& max_distance) {
  if (threads < 1 || threads > 1024) throw Error(ErrorKind::Usage, "--threads: must be between 1 and 1024");
  const Mesh m = s.get();
  if (!((points.ndim() == 2 && points.shape(1) == 3) || (points.ndim() == 1 && points.shape(0) == 3)))
    throw Error(ErrorKind::Usage, "locate: points must be an (n, 3) array (or one point of 3 numbers)");
  const std::vector<double> xyz(points.data(), points.data() + points.size());
  std::vector<Located> found;
  {
    ReleaseGil release;
    found = locate_points(*m, xyz, static_cast<int>(threads), max_distance.value_or(INFINITY));
  }
  const bool surface = m->mode() == Mode::Surface;
  const int dims = surface ? 2 : 3;
  std::vector<Id> ids(found.size());
  std::vector<double> xi(static_cast<size_t>(dims) * found.size()), distance(found.size());
  for (size_t i = 0; i < found.size(); ++i) {
    ids[i] = found[i].element;
    for (int d = 0; d < dims; ++d) xi[dims * i + d] = found[i].xi[d];
    distance[i] = found[i].distance;
  }
  const auto n = static_cast<py::ssize_t>(found.size());
  if (surface) return py::make_tuple(owned(std::move(ids)), owned(std::move(xi), {n, 2}), owned(std::move(distance)));
  return py::make_tuple(owned(std::move(ids)), owned(std::move(xi), {n, 3}));
}

// ---- Transfer (transfer.hpp): the prolongation from one store to a
// nested, finer one; holds both meshes.

py::dict nesting_dict(const Nesting& n) {
  // The keys and order of `dicer transfer --check --json`.
  py::dict d;
  d["nested"] = n.nested;
  d["sheets"] = n.sheets;
  d["sheet"] = n.sheet;
  d["coarse_interval"] = n.coarse_interval;
  d["fine_interval"] = n.fine_interval;
  d["min_factor"] = n.min_factor;
  d["max_factor"] = n.max_factor;
  d["rows"] = n.rows;
  d["cols"] = n.cols;
  d["moved_nodes_checked"] = n.moved_nodes_checked;
  d["moved_nodes_differ"] = n.moved_nodes_differ;
  d["message"] = n.message;
  return d;
}

struct Transfer {
  Mesh coarse, fine;
  std::shared_ptr<const Prolongation> p;
};

Transfer make_transfer(const Store& coarse, const Store& fine) {
  Transfer t{coarse.get(), fine.get(), nullptr};
  ReleaseGil release;
  t.p = std::make_shared<const Prolongation>(*t.coarse, *t.fine);
  return t;
}

using Vector = py::array_t<double, py::array::c_style | py::array::forcecast>;

py::array transfer_apply(const Transfer& t, const Vector& in, std::int64_t threads, bool transpose) {
  if (threads < 1 || threads > 1024) throw Error(ErrorKind::Usage, "--threads: must be between 1 and 1024");
  if (in.ndim() != 1) throw Error(ErrorKind::Usage, "transfer: a one-dimensional array of values, not " + std::to_string(in.ndim()) + "-dimensional");
  std::vector<double> out(static_cast<size_t>(transpose ? t.p->cols() : t.p->rows()));
  const std::span<const double> x(in.data(), static_cast<size_t>(in.size()));
  {
    ReleaseGil release;
    if (transpose) t.p->apply_transpose(x, out, static_cast<unsigned>(threads));
    else t.p->apply(x, out, static_cast<unsigned>(threads));
  }
  return owned(std::move(out));
}

py::dict sweep_dict(const Store& s, std::int64_t threads) {
  if (threads < 1 || threads > 1024) throw Error(ErrorKind::Usage, "--threads: must be between 1 and 1024");
  const Mesh m = s.get();
  SweepResult r;
  {
    ReleaseGil release;
    r = sweep(*m, static_cast<unsigned>(threads));
  }
  char checksum[24];
  std::snprintf(checksum, sizeof checksum, "%016llx", static_cast<unsigned long long>(r.checksum));
  // The keys and order of `dicer sweep --json`.
  py::dict d;
  d["nodes"] = r.nodes;
  d["elements"] = r.elements;
  d["seconds"] = r.seconds;
  d["nodes_per_s"] = r.seconds > 0 ? static_cast<double>(r.nodes) / r.seconds : 0.0;
  d["checksum"] = std::string(checksum);
  d["threads"] = r.threads;
  return d;
}

// ---- Chunks: the plan `dicer export --chunk K/N` uses.

std::vector<ChunkRange> checked_plan(const FineMesh& m, std::int64_t k, std::int64_t n) {
  const std::string what = "--chunk " + std::to_string(k) + "/" + std::to_string(n);
  if (n < 1 || k < 0 || k >= n) throw Error(ErrorKind::Usage, what + ": need 0 <= K < N (chunks are numbered from 0)");
  if (n > m.num_coarse_elements())
    throw Error(ErrorKind::Usage, what + ": the mesh has only " + std::to_string(m.num_coarse_elements()) +
                                      " coarse elements, so at most that many chunks");
  return plan_chunks(m, n);
}

py::dict range_dict(const ChunkRange& r) {
  py::dict d;
  d["index"] = r.index;
  d["count"] = r.count;
  d["first_coarse"] = r.first_coarse;
  d["end_coarse"] = r.end_coarse;
  d["fine_elements"] = r.fine_elements;
  d["node_begin"] = r.node_begin;
  d["node_end"] = r.node_end;
  return d;
}

MeshSets store_sets(const FineMesh& mesh, const std::string& path) {
  StoreSets s = read_store_sets(mesh, path);  // the uuid ties the sets to the mesh
  MeshSets sets;
  sets.side_sets = std::move(s.side_sets);
  sets.node_sets = std::move(s.node_sets);
  return sets;
}

struct Chunk {
  Mesh mesh;  // the ExportChunk refers to it
  std::unique_ptr<ExportChunk> chunk;
  std::vector<double> xyz;            // interleaved once, at construction
  std::vector<std::int64_t> block_id; // file ids of the elements' blocks
};

std::int64_t block_file_id(const FineMesh& m, std::int32_t index) { return m.info().blocks.at(static_cast<size_t>(index)).id; }

std::unique_ptr<Chunk> make_chunk(const Store& s, std::int64_t k, std::int64_t n) {
  auto c = std::make_unique<Chunk>();
  c->mesh = s.get();
  const FineMesh& m = *c->mesh;
  const std::string file = s.reread();
  SignalPoll poll;
  without_gil(poll, [&] {
    std::vector<ChunkRange> plan = checked_plan(m, k, n);
    c->chunk = std::make_unique<ExportChunk>(m, plan[static_cast<size_t>(k)]);
    c->chunk->set_plan(std::move(plan));
    c->chunk->prepare(store_sets(m, file), {}, [&] { return poll.poll(); });
    c->xyz = interleave(c->chunk->x(), c->chunk->y(), c->chunk->z());
    c->block_id.reserve(c->chunk->element_block().size());
    for (const std::int32_t b : c->chunk->element_block()) c->block_id.push_back(block_file_id(m, b));
  });
  return c;
}

// A chunk's side or node sets: [{id, name, members...}], members by `fill`.
template <class Set, class Fill>
py::list set_list(const std::vector<Set>& sets, Fill fill) {
  py::list out;
  for (const Set& s : sets) {
    py::dict d;
    d["id"] = s.id;
    d["name"] = text(s.name);
    fill(d, s);
    out.append(d);
  }
  return out;
}

// ---- Partitions (partition.hpp): rank r of P in one process.

struct PartitionBox {
  Mesh mesh;
  std::unique_ptr<Partition> part;
  std::vector<double> xyz;
};

std::unique_ptr<PartitionBox> make_partition(const Store& s, std::int64_t rank, std::int64_t size) {
  auto p = std::make_unique<PartitionBox>();
  p->mesh = s.get();
  const FineMesh& m = *p->mesh;
  const std::string file = s.reread();
  SignalPoll poll;
  without_gil(poll, [&] {
    const std::vector<ChunkRange> plan = checked_plan(m, rank, size);
    std::vector<std::vector<NodeRun>> sharing = in_process_sharing(m, plan);
    p->part = std::make_unique<Partition>(m, plan, rank, std::move(sharing[static_cast<size_t>(rank)]),
                                          store_sets(m, file), std::function<void(Id, Id)>{},
                                          [&] { return poll.poll(); });
    p->xyz = interleave(p->part->x(), p->part->y(), p->part->z());
  });
  return p;
}

// The partition of this rank of an mpi4py communicator, sharing exchanged
// over MPI (mpi::make_partition). Collective: every rank of comm calls it.
std::unique_ptr<PartitionBox> make_partition_mpi(const Store& s, const py::object& comm) {
  // An mpi4py.MPI.Comm, not anything with py2f (MPI.MAX and MPI.INFO_NULL
  // have one, and their handles read as COMM_WORLD or COMM_SELF).
  const py::object comm_type =
      py::module_::import("sys").attr("modules").attr("get")("mpi4py.MPI", py::none());
  if (comm_type.is_none() || !py::isinstance(comm, comm_type.attr("Comm")))
    throw Error(ErrorKind::Usage, "partition(comm): comm must be an mpi4py communicator, an mpi4py.MPI.Comm "
                                  "(or give rank, size)");
  int initialized = 0;
  MPI_Initialized(&initialized);
  if (!initialized) throw Error(ErrorKind::Usage, "partition(comm): MPI is not initialised (import mpi4py.MPI first)");
  // Through the Fortran handle: no mpi4py headers needed, and the same
  // Open MPI library on both sides (Debian's mpi4py links it too).
  const MPI_Comm c = MPI_Comm_f2c(comm.attr("py2f")().cast<MPI_Fint>());
  if (c == MPI_COMM_NULL)
    throw Error(ErrorKind::Usage, "partition(comm): comm is MPI.COMM_NULL (a rank that a Split left out has no partition)");
  int inter = 0;
  MPI_Comm_test_inter(c, &inter);
  if (inter) throw Error(ErrorKind::Usage, "partition(comm): comm is an intercommunicator; give an intracommunicator");
  auto p = std::make_unique<PartitionBox>();
  const Store* store = &s;
  std::string path;
  ReleaseGil release;
  MeshSets sets;
  // What only this rank can get wrong (a closed store, an unreadable file)
  // is agreed on first, so no rank waits in the exchange for one that failed.
  mpi::collectively(c, [&] {
    py::gil_scoped_acquire gil;  // Store::get() reads a Python-owned object
    p->mesh = store->get();
    path = store->reread();
  });
  mpi::require_same_store(c, path, p->mesh->info().uuid);
  mpi::collectively(c, [&] { sets = store_sets(*p->mesh, path); });
  p->part = std::make_unique<Partition>(mpi::make_partition(*p->mesh, c, sets));
  p->xyz = interleave(p->part->x(), p->part->y(), p->part->z());
  return p;
}

// ---- blocks(): one batch per coarse element.

struct Batch {
  py::array node_ids, points, connectivity, owned_mask;
  Id first_element = 0, num_elements = 0, coarse_element = 0, node_first = 0;
  std::int64_t block_id = 0;
};

// One step of an iterator at a time, as Python's generators: step()
// releases the GIL while it fills the iterator's buffers, so a second
// thread calling next() on the same iterator would fill them under the
// first (wrong batches, freed memory). Checked and set under the GIL.
class Stepping {
 public:
  explicit Stepping(bool& busy) : busy_(busy) {
    if (busy_) throw py::value_error("dicer iterator already executing (next() from two threads at once)");
    busy_ = true;
  }
  ~Stepping() { busy_ = false; }
  Stepping(const Stepping&) = delete;
  Stepping& operator=(const Stepping&) = delete;

 private:
  bool& busy_;
};

struct BlockIterator {
  Mesh mesh;
  bool busy = false;
  Id next = 0, end = 0;
  bool connectivity = true;
  FineBlock block;
  // The points are interleaved anyway: into a recycled array (1.10x at
  // interval 20, 1.04x at 10 over a fresh vector; bench/README.md
  // "Python"). Ids and connectivity are the block's own vectors handed
  // over (copying them into recycled arrays measured 0.80x).
  std::shared_ptr<Recycler<double>> points = std::make_shared<Recycler<double>>();

  Batch step() {
    const Stepping one(busy);
    if (next >= end) throw py::stop_iteration();
    const FineMesh& m = *mesh;
    std::vector<Id> ids, conn;
    {
      ReleaseGil release;
      m.fill_block(next, block, !connectivity);
    }
    auto xyz = points->array({static_cast<py::ssize_t>(block.x.size()), 3});
    double* p = xyz.mutable_data();
    {
      ReleaseGil release;
      interleave_into(block.x, block.y, block.z, p);
      // Handed over, not copied: fill_block refills them next time.
      ids = std::move(block.node_id);
      conn = std::move(block.conn);
      block.node_id.clear();
      block.conn.clear();
    }
    Batch b;
    b.first_element = block.first_element;
    b.num_elements = block.num_elements();
    b.coarse_element = block.coarse_element;
    b.node_first = block.node_first;
    b.block_id = block_file_id(m, block.block);
    std::vector<std::uint8_t> own(ids.size());
    for (size_t i = 0; i < ids.size(); ++i) own[i] = ids[i] >= block.node_first;
    py::array own_arr = owned(std::move(own));
    b.owned_mask = own_arr.attr("view")("bool");
    b.node_ids = owned(std::move(ids));
    b.points = std::move(xyz);
    const py::ssize_t elements = connectivity ? static_cast<py::ssize_t>(conn.size()) / m.corners() : 0;
    b.connectivity = owned(std::move(conn), {elements, m.corners()});
    ++next;
    return b;
  }
};

// Coarse elements [first, end) of chunk (k, n), or of the whole mesh (None).
std::pair<Id, Id> coarse_range(const FineMesh& m, const py::object& chunk) {
  if (chunk.is_none()) return {0, m.num_coarse_elements()};
  // (k, n) as a tuple, list or array; anything else is the caller's error,
  // said as such (pybind11's cast said "RuntimeError: Unable to cast").
  if (!py::isinstance<py::sequence>(chunk) || py::isinstance<py::str>(chunk) || py::isinstance<py::bytes>(chunk) ||
      py::len(chunk) != 2)
    throw Error(ErrorKind::Usage, "chunk: " + quoted(chunk) + " is not (k, n), two whole numbers");
  const py::sequence seq = chunk.cast<py::sequence>();
  const std::pair<Id, Id> kn{whole_id(seq[0], "chunk (k, n): k"), whole_id(seq[1], "chunk (k, n): n")};
  const ChunkRange r = checked_plan(m, kn.first, kn.second)[static_cast<size_t>(kn.first)];
  return {r.first_coarse, r.end_coarse};
}

BlockIterator make_blocks(const Store& s, const py::object& chunk, bool connectivity) {
  BlockIterator it;
  it.mesh = s.get();
  it.connectivity = connectivity;
  std::tie(it.next, it.end) = coarse_range(*it.mesh, chunk);
  return it;
}

// ---- batches(): the batch iteration of include/dicer/batch.hpp.

struct IdBatch {
  Id coarse_element = 0, node_begin = 0, node_end = 0, element_begin = 0, element_end = 0;
  py::array points, connectivity;
};

struct BatchIterator {
  Mesh mesh;
  bool busy = false;
  std::unique_ptr<BatchCursor> cursor;
  std::shared_ptr<Recycler<double>> xyz = std::make_shared<Recycler<double>>();
  std::shared_ptr<Recycler<Id>> conn = std::make_shared<Recycler<Id>>();

  // The batch's arrays are the caller's (the cursor reuses its buffers):
  // copied once, outside the GIL, into Recycler arrays (bench/README.md
  // "Python": by way of fresh std::vectors, each value was zeroed, written
  // and copied, and each step's pages faulted in anew).
  IdBatch step() {
    const Stepping one(busy);
    FineBatch b;
    bool more = false;
    {
      ReleaseGil release;
      more = cursor->next(b);
    }
    if (!more) throw py::stop_iteration();
    DICER_ASSERT(b.x.size() == static_cast<size_t>(b.num_nodes()) &&
                     b.conn.size() == static_cast<size_t>(b.num_elements() * b.corners),
                 "batches(): a batch's arrays match its id ranges");
    IdBatch r;
    r.coarse_element = b.coarse_element;
    r.node_begin = b.node_begin, r.node_end = b.node_end;
    r.element_begin = b.element_begin, r.element_end = b.element_end;
    auto points = xyz->array({static_cast<py::ssize_t>(b.num_nodes()), 3});
    auto ids = conn->array({static_cast<py::ssize_t>(b.num_elements()), b.corners});
    double* p = points.mutable_data();
    Id* c = ids.mutable_data();
    {
      ReleaseGil release;
      interleave_into(b.x, b.y, b.z, p);
      std::copy(b.conn.begin(), b.conn.end(), c);
    }
    r.points = std::move(points);
    r.connectivity = std::move(ids);
    return r;
  }
};

BatchIterator make_batches(const Store& s, const py::object& chunk, std::int64_t slab_points) {
  BatchIterator it;
  it.mesh = s.get();
  const auto [first, end] = coarse_range(*it.mesh, chunk);
  if (slab_points < 1) throw Error(ErrorKind::Usage, "batches: slab_points must be >= 1");
  BatchOptions opt;
  opt.slab_points = slab_points;
  it.cursor = std::make_unique<BatchCursor>(*it.mesh, first, end, opt);
  return it;
}

// ---- dice (without CAD: the package runs dicer-cad for --geometry)

py::dict dice_to_store(const std::string& mesh_path, const std::string& out, std::optional<std::int64_t> interval,
                       std::optional<double> size, const std::map<std::string, std::vector<std::string>>& options,
                       std::optional<std::string> intervals_file) {
  // The command line's words (python/dicer/__init__.py writes them), read
  // by the CLI's own parser.
  IntervalOptionText option_text;
  const std::pair<const char*, std::vector<std::string>*> fields[] = {
      {"block_interval", &option_text.block_interval}, {"sheet_interval", &option_text.sheet_interval},
      {"entity_interval", &option_text.entity_interval}, {"sheet_bias", &option_text.sheet_bias},
      {"sheet_dual_bias", &option_text.sheet_dual_bias}, {"block_bias", &option_text.block_bias},
      {"entity_bias", &option_text.entity_bias}};
  for (const auto& option : options) {  // not a structured binding: clang 14 does not capture one
    const std::string& name = option.first;
    const auto f = std::find_if(std::begin(fields), std::end(fields), [&](const auto& x) { return name == x.first; });
    if (f == std::end(fields)) throw Error(ErrorKind::Usage, "_dice: unknown option " + name);
    *f->second = option.second;
  }
  std::vector<std::string> warnings, notes;
  Id coarse = 0, nodes = 0, elements = 0;
  SignalPoll poll;
  without_gil(poll, [&] {
    // The CLI's order: the file first, flags over it (cli/command.cpp).
    IntervalRequest file;
    if (intervals_file) file = read_interval_file(*intervals_file);
    IntervalRequest flags = parse_interval_options(option_text);
    flags.global = interval;
    flags.size = size;
    const IntervalRequest request = merge(file, flags);
    CoarseMesh mesh = read_coarse_mesh(mesh_path);
    warnings = mesh.warnings;
    const auto page_written = [&](std::int64_t, std::int64_t) {
      // Thrown from the page callback: write_store removes its temporary.
      if (poll.poll()) throw Error(ErrorKind::Cancelled, "interrupted; nothing written to " + out);
    };
    // As the CLI without --geometry: second-order input moves nodes in
    // tables compiled into memory (quadratic.hpp); a linear mesh's rows
    // stream into the store (diced_rows.hpp).
    if (mesh.second_order()) {
      FineMesh fine = FineMesh::dice(std::move(mesh), request, &notes);
      apply_second_order(fine);
      if (poll.poll()) throw Error(ErrorKind::Cancelled, "interrupted; nothing written to " + out);
      write_store(fine, out, page_written);
      coarse = fine.num_coarse_elements(), nodes = fine.num_nodes(), elements = fine.num_elements();
    } else {
      const DicedRows rows(std::move(mesh), request, &notes);
      if (poll.poll()) throw Error(ErrorKind::Cancelled, "interrupted; nothing written to " + out);
      write_store(rows, out, page_written);
      coarse = rows.info().coarse_elements, nodes = rows.info().nodes, elements = rows.info().elements;
    }
  });
  py::dict d;
  py::list w, n;
  for (const auto& x : warnings) w.append(text(x));
  for (const auto& x : notes) n.append(text(x));
  d["warnings"] = w;
  d["notes"] = n;
  d["coarse_elements"] = coarse;
  d["nodes"] = nodes;
  d["elements"] = elements;
  return d;
}

}  // namespace
}  // namespace dicer::py_module

PYBIND11_MODULE(_core, m) {
  using namespace dicer;
  using namespace dicer::py_module;
  m.doc() = "dicer's C++ library (use the `dicer` package, not this module)";
  m.attr("__version__") = kVersion;
  m.attr("STORE_FORMAT_VERSION") = kStoreFormatVersion;
  register_errors(m);
  // numpy imported and pybind11's handle on its C API made now, while the
  // import holds the GIL alone: made lazily, by the first call returning an
  // array, two threads deadlocked (one in the static initialiser importing
  // numpy, which waits for the GIL the other holds while it waits for the
  // initialiser).
  py::module_::import("numpy");
  (void)py::array_t<double>(0);

  m.def("_dice", &dice_to_store, py::arg("mesh"), py::arg("out"), py::arg("interval"), py::arg("size"),
        py::arg("options"), py::arg("intervals_file"));
  m.def("_open", &open_store, py::arg("path"), py::arg("cache_mb"), py::arg("read_ahead"), py::arg("keep_tables"));
  m.def("_check_open_options", &check_open_options, py::arg("cache_mb"), py::arg("read_ahead"));

  py::class_<Batch>(m, "Batch",
                    "The fine nodes and elements of one coarse element: node_ids, points (n, 3) and "
                    "connectivity (e, 8|4, global node ids, VTK order) over ALL its grid points; "
                    "owned[i] is True for the points this coarse element owns (node_ids >= node_first), "
                    "so keeping only owned points visits every fine node exactly once. Unpacks as "
                    "(node_ids, points, connectivity).")
      .def_readonly("node_ids", &Batch::node_ids, "int64 (n,): the global id of each grid point of the coarse element")
      .def_readonly("points", &Batch::points, "float64 (n, 3): x, y, z of each grid point, rows as node_ids")
      .def_readonly("connectivity", &Batch::connectivity, "int64 (e, 8|4): global node ids per element, VTK/Exodus order (e = 0 with connectivity=False)")
      .def_readonly("owned", &Batch::owned_mask, "bool (n,): True where this coarse element owns the point (node_ids >= node_first)")
      .def_readonly("first_element", &Batch::first_element, "fine id of the first element; they are consecutive")
      .def_readonly("coarse_element", &Batch::coarse_element, "index in the store's (Morton) order")
      .def_readonly("node_first", &Batch::node_first, "the first node id this coarse element owns; its owned ids are consecutive from it")
      .def_readonly("block_id", &Batch::block_id, "the element block's id in the mesh file")
      .def_property_readonly("element_ids",
                             [](const Batch& b) {
                               py::module_ np = py::module_::import("numpy");
                               // From the block, not the connectivity: blocks(connectivity=False) has none.
                               return np.attr("arange")(b.first_element, b.first_element + b.num_elements,
                                                        py::arg("dtype") = "int64");
                             }, "int64 (e,): the fine element ids of the coarse element, first_element, first_element + 1, ... (the rows of connectivity; also with connectivity=False)")
      .def("__iter__", [](const Batch& b) { return py::iter(py::make_tuple(b.node_ids, b.points, b.connectivity)); })
      .def("__repr__", [](const Batch& b) {
        return "<dicer.Batch coarse element " + std::to_string(b.coarse_element) + ": " +
               std::to_string(b.node_ids.size()) + " points, " + std::to_string(b.num_elements) + " elements>";
      });

  py::class_<IdBatch>(m, "IdBatch",
                      "Consecutive fine ids of one slab (Store.batches): nodes node_begin..node_end-1 with "
                      "points (n, 3); elements element_begin..element_end-1 with connectivity (e, 8|4) in "
                      "global node ids. Unpacks as (node_begin, points, element_begin, connectivity).")
      .def_readonly("coarse_element", &IdBatch::coarse_element, "the coarse element the slab belongs to, in the store's order")
      .def_readonly("node_begin", &IdBatch::node_begin, "the first node id of the slab")
      .def_readonly("node_end", &IdBatch::node_end, "one past the last node id of the slab")
      .def_readonly("element_begin", &IdBatch::element_begin, "the first element id of the slab")
      .def_readonly("element_end", &IdBatch::element_end, "one past the last element id of the slab")
      .def_readonly("points", &IdBatch::points, "float64 (node_end - node_begin, 3): the slab's nodes in id order")
      .def_readonly("connectivity", &IdBatch::connectivity, "int64 (element_end - element_begin, 8|4): global node ids per element, VTK/Exodus order")
      .def("__iter__", [](const IdBatch& b) {
        return py::iter(py::make_tuple(b.node_begin, b.points, b.element_begin, b.connectivity));
      })
      .def("__repr__", [](const IdBatch& b) {
        return "<dicer.IdBatch coarse element " + std::to_string(b.coarse_element) + ": nodes " +
               std::to_string(b.node_begin) + ".." + std::to_string(b.node_end) + ", elements " +
               std::to_string(b.element_begin) + ".." + std::to_string(b.element_end) + ">";
      });

  py::class_<BatchIterator>(m, "BatchIterator",
                            "What Store.batches() returns: yields (n0, points, e0, connectivity) slab by slab in "
                            "id order; one next() at a time (another thread's next() meanwhile: ValueError)")
      .def("__iter__", [](BatchIterator& it) -> BatchIterator& { return it; })
      .def("__next__", &BatchIterator::step);

  py::class_<BlockIterator>(m, "BlockIterator",
                            "What Store.blocks() returns: yields a Batch per coarse element; len() is the number "
                            "left; one next() at a time (another thread's next() meanwhile: ValueError)")
      .def("__iter__", [](BlockIterator& it) -> BlockIterator& { return it; })
      .def("__next__", &BlockIterator::step)
      .def("__len__", [](const BlockIterator& it) { return it.end - it.next; });

  py::class_<Chunk>(m, "Chunk",
                    "Chunk k of n of the fine mesh (what `dicer export --chunk k/n` writes). Arrays are "
                    "read-only views into the chunk, no copies.")
      .def_property_readonly("index", [](const Chunk& c) { return c.chunk->range().index; }, "k: this chunk's number, from 0")
      .def_property_readonly("count", [](const Chunk& c) { return c.chunk->range().count; }, "n: the number of chunks the mesh was split into")
      .def_property_readonly("range", [](const Chunk& c) { return range_dict(c.chunk->range()); }, "dict: index, count, first_coarse, end_coarse (coarse elements), fine_elements, node_begin, node_end (the node ids it owns)")
      .def_property_readonly("mode", [](const Chunk& c) { return std::string(mode_name(c.chunk->mode())); }, "'volume' (hexes) or 'surface' (quads)")
      .def_property_readonly("num_nodes", [](const Chunk& c) { return c.chunk->num_nodes(); }, "nodes in the chunk, shared ones with other chunks included")
      .def_property_readonly("num_elements", [](const Chunk& c) { return c.chunk->num_elements(); }, "fine elements in the chunk")
      .def_property_readonly("points", [](py::object self) {
        const Chunk& c = self.cast<const Chunk&>();
        return view(std::span<const double>(c.xyz), {c.chunk->num_nodes(), 3}, self);
      }, "float64 (num_nodes, 3): x, y, z of each local node")
      .def_property_readonly("cells", [](py::object self) {
        const Chunk& c = self.cast<const Chunk&>();
        return view(c.chunk->connectivity(), {c.chunk->num_elements(), c.chunk->corners()}, self);
      }, "local node ids (rows of points), VTK/Exodus HEX8 or QUAD4 order")
      .def_property_readonly("global_node_ids", [](py::object self) { return view(self.cast<const Chunk&>().chunk->node_global(), self); }, "int64 (num_nodes,): the global id of each local node, ascending")
      .def_property_readonly("global_element_ids", [](py::object self) { return view(self.cast<const Chunk&>().chunk->element_global(), self); }, "int64 (num_elements,): the global id of each local element, ascending")
      .def_property_readonly("node_owner", [](py::object self) { return view(self.cast<const Chunk&>().chunk->node_owner(), self); },
                             "the lowest chunk holding each node")
      .def_property_readonly("block_ids", [](py::object self) {
        return view(std::span<const std::int64_t>(self.cast<const Chunk&>().block_id), self);
      }, "per element: its block's id in the mesh file")
      .def_property_readonly("block_index", [](py::object self) { return view(self.cast<const Chunk&>().chunk->element_block(), self); },
                             "per element: index into Store.info['blocks']")
      .def_property_readonly("block_names", [](const Chunk& c) {
        py::dict d;
        for (const auto& b : c.mesh->info().blocks) d[py::int_(b.id)] = text(b.name);
        return d;
      }, "dict: block id -> name, for every block of the mesh")
      .def_property_readonly("side_sets", [](const Chunk& c) {
        return set_list(c.chunk->side_sets(), [](py::dict& d, const ExportChunk::SideMembers& s) {
          d["element"] = owned(std::vector<Id>(s.element));
          d["side"] = owned(std::vector<std::int8_t>(s.side));
        });
      }, "[{id, name, element (local element index), side (0-based Exodus side)}]")
      .def_property_readonly("node_sets", [](const Chunk& c) {
        return set_list(c.chunk->node_sets(), [](py::dict& d, const ExportChunk::NodeMembers& s) {
          d["node"] = owned(std::vector<Id>(s.node));
        });
      }, "[{id, name, node (local node index)}]")
      .def("__repr__", [](const Chunk& c) {
        return "<dicer.Chunk " + std::to_string(c.chunk->range().index) + "/" + std::to_string(c.chunk->range().count) +
               ": " + std::to_string(c.chunk->num_nodes()) + " nodes, " + std::to_string(c.chunk->num_elements()) +
               " elements>";
      });

  py::class_<PartitionBox>(m, "Partition",
                           "Rank r of P (partition.hpp): owned nodes first (one global id range), then ghosts; "
                           "communication maps per neighbour. Arrays are read-only views.")
      .def_property_readonly("rank", [](const PartitionBox& p) { return p.part->rank(); }, "r: this partition's rank, from 0")
      .def_property_readonly("size", [](const PartitionBox& p) { return p.part->size(); }, "P: the number of partitions")
      .def_property_readonly("range", [](const PartitionBox& p) { return range_dict(p.part->range()); }, "dict: index, count, first_coarse, end_coarse, fine_elements, node_begin, node_end (the owned global node ids)")
      .def_property_readonly("num_owned", [](const PartitionBox& p) { return p.part->num_owned(); }, "nodes this rank owns: local nodes 0..num_owned-1, global ids range['node_begin']..")
      .def_property_readonly("num_nodes", [](const PartitionBox& p) { return p.part->num_nodes(); }, "local nodes: owned, then ghosts (owned by lower ranks)")
      .def_property_readonly("num_elements", [](const PartitionBox& p) { return p.part->num_elements(); }, "fine elements of this rank (each element on exactly one rank)")
      .def_property_readonly("element_begin", [](const PartitionBox& p) { return p.part->element_begin(); }, "the global id of the first local element; local element i is element_begin + i")
      .def_property_readonly("node_global", [](py::object self) { return view(self.cast<const PartitionBox&>().part->node_global(), self); }, "int64 (num_nodes,): local -> global node id")
      .def_property_readonly("node_owner", [](py::object self) { return view(self.cast<const PartitionBox&>().part->node_owner(), self); }, "int32 (num_nodes,): the rank that owns each local node")
      .def_property_readonly("points", [](py::object self) {
        const PartitionBox& p = self.cast<const PartitionBox&>();
        return view(std::span<const double>(p.xyz), {p.part->num_nodes(), 3}, self);
      }, "float64 (num_nodes, 3): x, y, z of each local node")
      .def_property_readonly("x", [](py::object self) { return view(self.cast<const PartitionBox&>().part->x(), self); }, "float64 (num_nodes,): x of each local node")
      .def_property_readonly("y", [](py::object self) { return view(self.cast<const PartitionBox&>().part->y(), self); }, "float64 (num_nodes,): y of each local node")
      .def_property_readonly("z", [](py::object self) { return view(self.cast<const PartitionBox&>().part->z(), self); }, "float64 (num_nodes,): z of each local node")
      .def_property_readonly("connectivity", [](py::object self) {
        const PartitionBox& p = self.cast<const PartitionBox&>();
        return view(p.part->connectivity(), {p.part->num_elements(), p.part->corners()}, self);
      }, "local node ids, VTK/Exodus HEX8 or QUAD4 order")
      .def_property_readonly("neighbors", [](const PartitionBox& p) { return p.part->neighbors(); }, "the ranks this one shares nodes with, ascending; shared_nodes[k] goes with neighbors[k]")
      .def_property_readonly("shared_nodes", [](py::object self) {
        const PartitionBox& p = self.cast<const PartitionBox&>();
        py::list out;
        for (const auto& s : p.part->shared_nodes()) out.append(view(std::span<const Id>(s), self));
        return out;
      }, "per neighbour: local ids of the nodes both use, sorted by global id")
      .def("__repr__", [](const PartitionBox& p) {
        return "<dicer.Partition rank " + std::to_string(p.part->rank()) + " of " + std::to_string(p.part->size()) + ": " +
               std::to_string(p.part->num_owned()) + " owned + " +
               std::to_string(p.part->num_nodes() - p.part->num_owned()) + " ghost nodes, " +
               std::to_string(p.part->num_elements()) + " elements>";
      });

  py::class_<Transfer>(m, "Transfer",
                       "The prolongation P from a coarse store to a nested finer one (store.transfer(fine)): "
                       "fine nodes x coarse nodes, both in id order, never formed")
      .def_property_readonly("shape", [](const Transfer& t) { return py::make_tuple(t.p->rows(), t.p->cols()); }, "(fine nodes, coarse nodes): P maps coarse nodal values to fine ones")
      .def_property_readonly("nonzeros", [](const Transfer& t) { return t.p->nonzeros(); }, "stored entries of P")
      .def_property_readonly("nesting", [](const Transfer& t) { return nesting_dict(t.p->nesting()); },
                             "the keys of `dicer transfer --check --json`")
      .def("apply", [](const Transfer& t, const Vector& x, const py::object& threads) {
        return transfer_apply(t, x, whole_id(threads, "apply: threads"), false);
      },
           py::arg("x"), py::arg("threads") = 1, "P x: coarse node values -> fine node values (float64)")
      .def("apply_transpose", [](const Transfer& t, const Vector& y, const py::object& threads) {
        return transfer_apply(t, y, whole_id(threads, "apply_transpose: threads"), true);
      },
           py::arg("y"), py::arg("threads") = 1, "P^T y: fine node values -> coarse node values, the same bits for any thread count")
      .def("__repr__", [](const Transfer& t) {
        return "<dicer.Transfer " + std::to_string(t.p->rows()) + " x " + std::to_string(t.p->cols()) + ", " +
               std::to_string(t.p->nonzeros()) + " non-zeros>";
      });

  py::class_<Store>(m, "Store", "A fine mesh kept in a dicer store (open with dicer.open or dicer.dice).")
      .def_property_readonly("path", [](const Store& s) { return path_text(s.path); }, "the path the store was opened by, as os.fsdecode gives it (a str; bytes that are not UTF-8 as surrogate escapes)")
      .def_readonly("warnings", &Store::warnings, "what the mesh reader accepted with a warning (from dice)")
      .def_readonly("notes", &Store::notes, "how interval conflicts were resolved (from dice)")
      .def_property_readonly("info", &info_dict, "the keys and values of `dicer info --json`")
      .def_property_readonly("num_nodes", [](const Store& s) { return s.get()->num_nodes(); }, "fine nodes; ids 0..num_nodes-1")
      .def_property_readonly("num_elements", [](const Store& s) { return s.get()->num_elements(); }, "fine elements; ids 0..num_elements-1")
      .def_property_readonly("num_coarse_elements", [](const Store& s) { return s.get()->num_coarse_elements(); }, "coarse elements (hexes or quads) the fine mesh refines")
      .def_property_readonly("mode", [](const Store& s) { return std::string(mode_name(s.get()->mode())); }, "'volume' (hexes) or 'surface' (quads)")
      .def_property_readonly("corners", [](const Store& s) { return s.get()->corners(); }, "nodes per element: 8 (volume) or 4 (surface)")
      .def_property_readonly("closed", [](const Store& s) { return !s.mesh; }, "True after close(); every other call then raises UsageError")
      .def("cache_stats", &cache_stats, "the page cache's counters (what --stats prints)")
      .def("nodes", &nodes, py::arg("start"), py::arg("stop") = py::none(),
           "nodes(start, stop) or nodes(ids): coordinates, float64 (n, 3)")
      .def("elements", &elements, py::arg("start"), py::arg("stop") = py::none(),
           "elements(start, stop) or elements(ids): node ids, int64 (n, 8) (surface: (n, 4)), VTK/Exodus order")
      .def("element_info", &element_info, py::arg("start"), py::arg("stop") = py::none(),
           "like elements(), with block (file id), coarse_element and ijk, as `dicer query --elements --json`")
      .def("elements_in_box", &elements_in_box, py::arg("lo"), py::arg("hi"),
           "ids of the fine elements whose centroid lies in the box (`dicer query --box`)")
      .def("element_neighbors", [](const Store& s, const py::object& id) {
        const Mesh m = s.get();
        return owned(element_neighbors(*m, whole_id(id, "element_neighbors(id)")));
      }, py::arg("id"), "the fine elements across each side of element id in Exodus side order, -1 on the boundary "
                        "(`dicer query --element-neighbors`)")
      .def("node_elements", [](const Store& s, const py::object& id) {
        const Mesh m = s.get();
        return owned(node_elements(*m, whole_id(id, "node_elements(id)")));
      }, py::arg("id"), "the fine elements using node id, ascending (`dicer query --node-elements`)")
      .def("locate", [](const Store& s, const py::object& points, const py::object& threads, const py::object& max_distance) {
        using Points = py::array_t<double, py::array::c_style | py::array::forcecast>;
        const auto refuse = [&] {
          return Error(ErrorKind::Usage, "locate: points must be an (n, 3) array of numbers, not " + quoted(points));
        };
        if (py::isinstance<py::str>(points) || py::isinstance<py::bytes>(points)) throw refuse();
        const Points xyz = Points::ensure(points);
        if (!xyz) throw refuse();
        return locate(s, xyz, whole_id(threads, "locate: threads"),
                      max_distance.is_none() ? std::optional<double>()
                                             : std::optional<double>(finite_value(max_distance, "--max-distance")));
      }, py::arg("points"), py::arg("threads") = 1, py::arg("max_distance") = py::none(),
           "as `dicer query --points`. Volume stores: (element ids, xi (n, 3)) of an (n, 3) array of points: "
           "the fine element containing each (-1: none; the lowest id on a shared face) and the local "
           "coordinates in it. Surface stores: (element ids, xi (n, 2), distances): the nearest fine quad "
           "(-1: none within max_distance, distance inf), the nearest point's xi on it and its distance; "
           "max_distance on a volume store is a UsageError")
      .def("blocks", [](const Store& s, const py::object& chunk, const py::object& connectivity) {
        return make_blocks(s, chunk, switch_value(connectivity, "blocks: connectivity"));
      }, py::arg("chunk") = py::none(), py::arg("connectivity") = true,
           "iterator of Batch, one per coarse element, over the mesh or over chunk (k, n)")
      .def("batches", [](const Store& s, const py::object& chunk, const py::object& slab_points) {
        return make_batches(s, chunk, whole_id(slab_points, "batches: slab_points"));
      }, py::arg("chunk") = py::none(), py::arg("slab_points") = kCursorSlabPoints,
           "iterator of IdBatch over the mesh (or chunk (k, n)) in id order, a slab of a coarse element at a "
           "time: the nodes node_begin..node_end-1 (points, (n, 3)) and elements element_begin..element_end-1 "
           "(connectivity, (e, 8|4), global node ids); every node and element exactly once, consecutive ids")
      .def("chunk_ranges", [](const Store& s, const py::object& n) {
        const Mesh m = s.get();
        py::list out;
        for (const auto& r : checked_plan(*m, 0, whole_id(n, "chunk_ranges(n): n"))) out.append(range_dict(r));
        return out;
      }, py::arg("n"), "the plan of n chunks: coarse element and owned node ranges")
      .def("chunk", [](const Store& s, const py::object& k, const py::object& n) {
        return make_chunk(s, whole_id(k, "chunk(k, n): k"), whole_id(n, "chunk(k, n): n"));
      }, py::arg("k"), py::arg("n"), "chunk k of n (as `dicer export --chunk k/n`)")
      .def("partition", [](const Store& s, const py::object& rank, const py::object& size) {
        return make_partition(s, whole_id(rank, "partition(rank, size): rank"), whole_id(size, "partition(rank, size): size"));
      }, py::arg("rank"), py::arg("size"),
           "the partition of rank `rank` of `size`, sharing computed in this process")
      .def("partition", &make_partition_mpi, py::arg("comm"),
           "this rank's partition of an mpi4py communicator (collective), sharing exchanged over MPI")
      .def("nesting", [](const Store& s, const Store& fine) {
        const Mesh c = s.get(), f = fine.get();
        ReleaseGil release;
        const Nesting n = check_nesting(*c, *f);
        py::gil_scoped_acquire acquire;
        return nesting_dict(n);
      }, py::arg("fine"), "whether `fine` is nested in this store (`dicer transfer --check --json`)")
      .def("transfer", &make_transfer, py::arg("fine"),
           "the prolongation from this store to `fine`, a nested dicing of the same coarse mesh (BadInputError if not)")
      .def("sweep", [](const Store& s, const py::object& threads) { return sweep_dict(s, whole_id(threads, "sweep: threads")); },
           py::arg("threads") = 2, "as `dicer sweep --json`: counts, time, checksum")
      .def("_set_report", [](Store& s, std::vector<std::string> warnings, std::vector<std::string> notes) {
        s.warnings = std::move(warnings);
        s.notes = std::move(notes);
      })
      .def("close", [](Store& s) { s.mesh.reset(); }, "release the store's hold on the file and the cache; what was made from it (chunks, partitions, "
           "transfers, live blocks()/batches() iterators) keeps its own reference, and the file stays open until those go")
      .def("__enter__", [](Store& s) -> Store& { return s; })
      .def("__exit__", [](Store& s, py::args) { s.mesh.reset(); })
      .def("__repr__", [](const Store& s) {
        if (!s.mesh) return text("<dicer.Store " + s.path + " (closed)>");
        return text("<dicer.Store " + s.path + ": " + std::string(mode_name(s.mesh->mode())) + ", " +
               std::to_string(s.mesh->num_nodes()) + " nodes, " + std::to_string(s.mesh->num_elements()) + " elements>");
      });
}
