// dicer query: fine nodes and elements by id.
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>

#include <sys/stat.h>

#include "command.hpp"
#include "common.hpp"
#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/locate.hpp"
#include "dicer/neighbors.hpp"
#include "json_out.hpp"

namespace dicer::cli {

static const CommandDoc kDoc = {
    "query",
    R"(query STORE (--node ID | --nodes FIRST:END | --element ID |
                   --elements FIRST:END | --box x0,y0,z0,x1,y1,z1 [--count] |
                   --point x,y,z | --points FILE [--threads N]
                   [--max-distance D] |
                   --element-neighbors ID | --node-elements ID)
                   [--json] [--quiet] [store options])",
    R"(Regenerates fine nodes or elements by id, by box or by point; ids start
at 0. Ranges are half-open: --nodes 1000:2000 prints ids 1000..1999, one
line each. Give exactly one of --node, --nodes, --element, --elements,
--box, --point, --points, --element-neighbors, --node-elements.

Node ids (owner order, since store format 6): coarse element by coarse element
in the store's order, the nodes of the vertices, edges and faces it owns
(the lowest coarse element containing them), then its interior; so the
nodes of any range of coarse elements, a chunk, are one id range. Element
ids: coarse element order, then i, j, k.
Coordinates are printed with 17 significant digits (text) or in the
shortest form that reads back exactly (JSON): both give the same bits.
)",
    R"(dicer query sphere.dice.h5 --node 123456 --json
dicer query sphere.dice.h5 --elements 0:500 --json
dicer query sphere.dice.h5 --box 0,0,0,1,1,0.5 --count
dicer query sphere.dice.h5 --point 0.1,0.2,0.3 --json
dicer query sphere.dice.h5 --points probes.txt --threads 2 > found.txt
dicer query skin.dice.h5 --point 0.1,0.2,0.3 --max-distance 0.05 --json
)"};

namespace {

// A few ids are answered one by one (node(id), element(id): the same bits
// as the cursors, O(1) memory); more stream through a cursor, which holds
// a slab of a coarse element's grid, O(interval^2): at interval 10,000
// that is gigabytes for one id.
constexpr Id kFewIds = 4096;

// Points for --point (one "x,y,z") or --points (a file or stdin, one
// "x y z" per line, commas allowed, blank lines and # comments skipped; or
// a NumPy .npy file of shape (n, 3), float64 or float32, C order).
class PointReader {
 public:
  PointReader(const std::string& file, const std::string& one) : file_(file), one_(one) {
    if (file_.empty()) return;
    file_handle_.reset(file_ == "-" ? stdin : std::fopen(file_.c_str(), "rb"));
    f_ = file_handle_.get();
    if (!f_) throw Error(ErrorKind::Io, file_ + ": cannot open: " + std::strerror(errno));
    // A FIFO streams points and is welcome; a directory opens but reads as an error.
    struct stat st {};
    if (::fstat(::fileno(f_), &st) == 0 && S_ISDIR(st.st_mode))
      throw Error(ErrorKind::Usage, file_ + ": --points is a directory, not a file of points");
    if (file_.size() > 4 && file_.compare(file_.size() - 4, 4, ".npy") == 0) open_npy();
  }
  PointReader(const PointReader&) = delete;
  PointReader& operator=(const PointReader&) = delete;

  bool next(std::vector<double>& out, size_t max_points) {
    out.clear();
    if (file_.empty()) {
      if (done_) return false;
      done_ = true;
      parse(one_, "--point", ErrorKind::Usage, out);
      return true;
    }
    if (npy_) {
      // The header gave the count: read what is left, a batch at a time.
      const size_t take = static_cast<size_t>(std::min<std::uint64_t>(npy_left_, max_points)) * 3;
      if (take == 0) return false;
      out.resize(take);
      if (npy_f4_) {
        std::vector<float> f(take);
        if (std::fread(f.data(), 4, take, f_) != take) throw Error(ErrorKind::BadInput, file_ + ": truncated .npy data");
        for (size_t i = 0; i < take; ++i) out[i] = f[i];
      } else if (std::fread(out.data(), 8, take, f_) != take) {
        throw Error(ErrorKind::BadInput, file_ + ": truncated .npy data");
      }
      for (double v : out)
        if (!std::isfinite(v)) throw Error(ErrorKind::BadInput, file_ + ": a coordinate is not finite");
      npy_left_ -= take / 3;
      return true;
    }
    std::string line;
    while (out.size() < 3 * max_points && read_line(line)) {
      ++line_no_;
      const size_t hash = line.find('#');
      if (hash != std::string::npos) line.resize(hash);
      if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
      parse(line, file_ + ":" + std::to_string(line_no_), ErrorKind::BadInput, out);
    }
    return !out.empty();
  }

 private:
  bool read_line(std::string& line) {
    line.clear();
    int c;
    while ((c = std::fgetc(f_)) != EOF && c != '\n') {
      if (line.size() > 4096) throw Error(ErrorKind::BadInput, file_ + ":" + std::to_string(line_no_ + 1) + ": line too long");
      line.push_back(static_cast<char>(c));
    }
    if (c == EOF && std::ferror(f_)) throw Error(ErrorKind::Io, file_ + ": read failed");
    return c != EOF || !line.empty();
  }
  // Three finite numbers separated by spaces, tabs or commas. `bad`: Usage
  // for --point's value, BadInput for a line of a file.
  static void parse(const std::string& text, const std::string& where, ErrorKind bad, std::vector<double>& out) {
    // The message quotes the start of a long line (a binary file's "line"
    // runs to 4 KiB); main shows what is not text as escapes.
    std::string quoted = text.size() > 60 ? text.substr(0, 60) + "..." : text;
    // A message is a C string: a NUL would end it (printable() escapes the rest).
    for (size_t at; (at = quoted.find('\0')) != std::string::npos;) quoted.replace(at, 1, "\\x00");
    // strtod stops at a NUL: the rest of the line was dropped, silently.
    if (text.find('\0') != std::string::npos) throw Error(bad, where + ": \"" + quoted + "\" holds a NUL byte");
    const char* p = text.c_str();
    for (int k = 0; k < 3; ++k) {
      while (*p == ' ' || *p == '\t' || *p == ',' || *p == '\r') ++p;
      char* end = nullptr;
      const double v = std::strtod(p, &end);
      if (end == p || !std::isfinite(v))
        throw Error(bad, where + ": \"" + quoted + "\" is not three finite numbers x y z");
      out.push_back(v);
      p = end;
    }
    while (*p == ' ' || *p == '\t' || *p == '\r') ++p;
    if (*p == '\0') return;
    char* end = nullptr;
    (void)std::strtod(*p == ',' ? p + 1 : p, &end);
    if (end != (*p == ',' ? p + 1 : p)) throw Error(bad, where + ": \"" + quoted + "\" has more than three numbers");
    const std::string rest(p, std::min<size_t>(std::strlen(p), 20));
    throw Error(bad, where + ": \"" + quoted + "\" is not three finite numbers x y z (\"" + rest + "\" after the third)");
  }

  // NumPy format 1.0-3.0: magic, version, header length, a Python dict
  // literal; NumPy's own reader is not available from C++, and the header
  // is a fixed, documented form.
  void open_npy() {
    unsigned char head[10];
    if (std::fread(head, 1, 8, f_) != 8 || std::memcmp(head, "\x93NUMPY", 6) != 0)
      throw Error(ErrorKind::BadInput, file_ + ": not a .npy file (no \\x93NUMPY magic)");
    std::uint32_t len = 0;
    if (head[6] == 1) {
      if (std::fread(head + 8, 1, 2, f_) != 2) throw Error(ErrorKind::BadInput, file_ + ": truncated .npy header");
      len = head[8] | (head[9] << 8);
    } else if (head[6] == 2 || head[6] == 3) {
      unsigned char l[4];
      if (std::fread(l, 1, 4, f_) != 4) throw Error(ErrorKind::BadInput, file_ + ": truncated .npy header");
      len = l[0] | (l[1] << 8) | (l[2] << 16) | (static_cast<std::uint32_t>(l[3]) << 24);
    } else {
      throw Error(ErrorKind::BadInput, file_ + ": .npy format version " + std::to_string(head[6]) + " is not read");
    }
    if (len > 65536) throw Error(ErrorKind::BadInput, file_ + ": .npy header of " + std::to_string(len) + " bytes");
    std::string h(len, '\0');
    if (std::fread(h.data(), 1, len, f_) != len) throw Error(ErrorKind::BadInput, file_ + ": truncated .npy header");
    h.erase(std::remove(h.begin(), h.end(), ' '), h.end());
    // Each key's own value (a substring search found '<f8' in any field).
    auto value_of = [&](const char* key) -> std::string {
      const std::string k = std::string("'") + key + "':";
      const size_t at = h.find(k);
      if (at == std::string::npos) throw Error(ErrorKind::BadInput, file_ + ": the .npy header has no '" + key + "'");
      const size_t from = at + k.size();
      const size_t to = h[from] == '(' ? h.find(')', from) + 1 : h[from] == '\'' ? h.find('\'', from + 1) + 1
                                                                                : h.find_first_of(",}", from);
      return h.substr(from, to == std::string::npos || to == 0 ? std::string::npos : to - from);
    };
    const std::string order = value_of("fortran_order"), descr = value_of("descr"), shape = value_of("shape");
    if (order != "False") throw Error(ErrorKind::BadInput, file_ + ": a Fortran-order .npy array (save it with C order)");
    if (descr == "'<f8'") npy_f4_ = false;
    else if (descr == "'<f4'") npy_f4_ = true;
    else throw Error(ErrorKind::BadInput, file_ + ": .npy points must be little-endian float64 or float32 ('<f8', '<f4')");
    // (n, 3) with n a plain count: strtoull took "-1" as 2^64 - 1.
    const size_t digits = shape.size() < 5 || shape[0] != '(' ? 1 : shape.find_first_not_of("0123456789", 1);
    errno = 0;
    const unsigned long long n = digits == 1 ? 0 : std::strtoull(shape.c_str() + 1, nullptr, 10);
    if (digits == 1 || digits == std::string::npos || shape.compare(digits, std::string::npos, ",3)") != 0 ||
        errno == ERANGE)
      throw Error(ErrorKind::BadInput, file_ + ": .npy points must have shape (n, 3), not " + shape);
    // A count the file cannot hold is said up front (a regular file).
    struct stat st {};
    const long here = std::ftell(f_);
    const unsigned long long item = npy_f4_ ? 12 : 24;
    if (here >= 0 && ::fstat(::fileno(f_), &st) == 0 && S_ISREG(st.st_mode) &&
        (n > (1ULL << 58) / item || static_cast<unsigned long long>(st.st_size - here) < n * item))
      throw Error(ErrorKind::BadInput, file_ + ": the .npy header's shape (" + std::to_string(n) + ", 3) needs " +
                                           std::to_string(n) + " x " + std::to_string(item) + " bytes; the file holds " +
                                           std::to_string(st.st_size - here));
    npy_ = true;
    npy_left_ = n;
  }

  std::string file_, one_;
  // Closed however the constructor ends (a refused .npy header throws); stdin stays open.
  struct Close {
    void operator()(std::FILE* f) const {
      if (f != stdin) std::fclose(f);
    }
  };
  std::unique_ptr<std::FILE, Close> file_handle_;
  std::FILE* f_ = nullptr;  // file_handle_.get()
  bool npy_ = false, npy_f4_ = false;
  std::uint64_t npy_left_ = 0;
  bool done_ = false;
  long line_no_ = 0;
};

// `chunk_count`: under mpirun with --box --count, this rank's count in its
// chunk is stored there and nothing is printed (the caller sums); `opened`
// receives the store's path and uuid (check_same_store).
int query(const std::vector<std::string>& argv, long long* chunk_count = nullptr, bool* as_json = nullptr,
          std::pair<std::string, std::string>* opened = nullptr) {
  Command cmd(kDoc);
  std::string path, node, nodes, element, elements, box_text, point_text, points_file, neighbors_of, elements_of;
  std::string threads_text = "1", max_distance_text;
  bool json = false, count_only = false;
  cmd.input("STORE", path, "the store to read");
  auto* o_node = cmd.value("--node", node, "ID", "the fine node ID: its coordinates");
  auto* o_nodes = cmd.value("--nodes", nodes, "FIRST:END", "the fine nodes FIRST..END-1, one per line");
  auto* o_element = cmd.value("--element", element, "ID",
                              "the fine element ID: its nodes (VTK/Exodus HEX8 "
                              "order; surface meshes: QUAD4), block id, coarse "
                              "element and ijk in it");
  auto* o_elements = cmd.value("--elements", elements, "FIRST:END", "the fine elements FIRST..END-1, one per line");
  auto* o_box = cmd.value("--box", box_text, "x0,y0,z0,x1,y1,z1",
                          "the ids of the fine elements whose centroid lies in the "
                          "axis-aligned box (one per line); groups of coarse "
                          "elements and coarse elements whose bounds (the "
                          "store's spatial index) miss it are skipped unread");
  auto* o_count = cmd.flag("--count", count_only, "with --box: only the number of such elements");
  auto* o_point = cmd.value("--point", point_text, "x,y,z",
                            "volume stores: the fine element containing the point "
                            "and the point's local coordinates xi in it (its "
                            "trilinear map at xi gives the point), -1 when none "
                            "does; on a shared face, edge or node the lowest id. "
                            "Surface stores: the nearest fine quad, xi of the "
                            "nearest point on it (its bilinear map at xi) and "
                            "the distance; the lowest id among quads as near");
  auto* o_points = cmd.value("--points", points_file, "FILE",
                             "as --point for every line \"x y z\" of FILE (- reads "
                             "standard input, a FIFO streams; blank lines and # comments are "
                             "skipped) or every row of an (n, 3) .npy array, "
                             "one answer per point in input order");
  auto* o_threads = cmd.value("--threads", threads_text, "N", "with --points: threads searching (1 to 1024)");
  auto* o_max_distance = cmd.value("--max-distance", max_distance_text, "D",
                                   "surface stores, with --point or --points: -1 and "
                                   "distance inf (JSON: null) for points farther than "
                                   "D from every quad (default: "
                                   "no limit; the search reads less the smaller D is)");
  auto* o_neighbors = cmd.value("--element-neighbors", neighbors_of, "ID",
                                "the fine elements across each side of element ID "
                                "in Exodus side order (HEX8: 6 faces, QUAD4: 4 "
                                "edges), -1 on the boundary");
  auto* o_node_elements = cmd.value("--node-elements", elements_of, "ID", "the fine elements that use node ID, ascending");
  cmd.flag("--json", json,
           "one JSON object per line:\n"
           "node:    {\"id\":..., \"xyz\":[x,y,z]}\n"
           "element: {\"id\":..., \"nodes\":[8 ids], \"block\":...,\n"
           "          \"coarse_element\":..., \"ijk\":[i,j,k]}\n"
           "          (surface meshes: 4 node ids and [i,j])\n"
           "box:     {\"id\":...} per element, or {\"count\":...}\n"
           "point:   {\"point\":[x,y,z], \"element\":..., \"xi\":[a,b,c]}\n"
           "         (surface: \"xi\":[a,b], \"distance\":d)\n"
           "neighbors: {\"id\":..., \"neighbors\":[6 or 4 ids]}\n"
           "node elements: {\"node\":..., \"elements\":[ids]}");
  cmd.quiet_accepted();
  StoreFlags store(cmd);
  if (!cmd.parse(argv)) return 0;
  const int chosen = cmd.given(o_node) + cmd.given(o_nodes) + cmd.given(o_element) + cmd.given(o_elements) +
                     cmd.given(o_box) + cmd.given(o_point) + cmd.given(o_points) + cmd.given(o_neighbors) +
                     cmd.given(o_node_elements);
  if (chosen != 1)
    throw Error(ErrorKind::Usage,
                "give exactly one of --node, --nodes, --element, --elements, --box, --point, --points, "
                "--element-neighbors, --node-elements");
  const Id threads = parse_threads(threads_text);
  if (cmd.given(o_count) && !cmd.given(o_box)) throw Error(ErrorKind::Usage, "--count goes with --box");
  if (cmd.given(o_threads) && !cmd.given(o_points)) throw Error(ErrorKind::Usage, "--threads goes with --points");
  if (cmd.given(o_max_distance) && !cmd.given(o_point) && !cmd.given(o_points))
    throw Error(ErrorKind::Usage, "--max-distance goes with --point or --points");
  const double max_distance = cmd.given(o_max_distance) ? parse_double("--max-distance", max_distance_text) : INFINITY;
  if (!(max_distance >= 0)) throw Error(ErrorKind::Usage, "--max-distance: must be 0 or more");

  const FineMesh m = read_store(path, store.options());
  // --node-elements / --element-neighbors: one id in, a list of ids out.
  auto print_list = [&](const char* what, const char* key, Id id, const char* list, const std::vector<Id>& ids) {
    if (json) {
      print_json({{key, id}, {list, ids}});
    } else {
      std::printf("%s %lld %s", what, static_cast<long long>(id), list);
      for (Id e : ids) std::printf(" %lld", static_cast<long long>(e));
      std::printf("\n");
    }
    store.report(m);
    return 0;
  };
  if (cmd.given(o_node_elements) || cmd.given(o_neighbors)) {
    const bool of_node = cmd.given(o_node_elements);
    const std::string flag = of_node ? "--node-elements" : "--element-neighbors";
    const auto [a, b] = parse_range(flag, of_node ? elements_of : neighbors_of);
    if (b != a + 1) throw Error(ErrorKind::Usage, flag + " takes one " + (of_node ? "node" : "element") + " id");
    return of_node ? print_list("node", "node", a, "elements", node_elements(m, a))
                   : print_list("element", "id", a, "neighbors", element_neighbors(m, a));
  }
  if (cmd.given(o_points) && points_file.empty())
    throw Error(ErrorKind::Usage, "--points: the file name is empty (- reads standard input)");
  if (cmd.given(o_point) || cmd.given(o_points)) {
    // Batches of 65536 points bound the memory of a long stream; answers
    // come in input order.
    // The library's refusals (--max-distance on a volume store) before
    // anything is read: an empty file, or a pipe's first 65536 points.
    locate_points(m, {}, 1, max_distance);
    PointReader in(cmd.given(o_point) ? std::string() : points_file, point_text);
    std::vector<double> part;
    while (in.next(part, 65536)) {
      const std::vector<Located> found = locate_points(m, part, static_cast<int>(threads), max_distance);
      const bool surface = m.mode() == Mode::Surface;
      for (size_t i = 0; i < found.size(); ++i) {
        const double* p = &part[3 * i];
        const Located& l = found[i];
        if (json && surface)
          print_json({{"point", {p[0], p[1], p[2]}}, {"element", l.element}, {"xi", {l.xi[0], l.xi[1]}}, {"distance", l.distance}});
        else if (json)
          print_json({{"point", {p[0], p[1], p[2]}}, {"element", l.element}, {"xi", {l.xi[0], l.xi[1], l.xi[2]}}});
        else if (surface)
          std::printf("%lld  %.17g %.17g  %.17g\n", static_cast<long long>(l.element), l.xi[0], l.xi[1], l.distance);
        else
          std::printf("%lld  %.17g %.17g %.17g\n", static_cast<long long>(l.element), l.xi[0], l.xi[1], l.xi[2]);
      }
    }
    store.report(m);
    return 0;
  }
  if (cmd.given(o_box)) {
    const Box box = parse_box(box_text);
    if (chunk_count && count_only) {  // rank r counts in chunk r
      mpi::Session& mpi = session();
      const ChunkRange r = plan_chunks(m, mpi.size())[static_cast<size_t>(mpi.rank())];
      *chunk_count = for_each_in_box(m, box, {}, r.first_coarse, r.end_coarse);
      if (as_json) *as_json = json;
      if (opened) *opened = {path, m.info().uuid};
      store.report(m);
      return 0;
    }
    const Id n = for_each_in_box(m, box, [&](const FineBlock& b, Id e) {
      if (count_only) return;
      const Id id = b.first_element + e;
      if (json) print_json({{"id", id}});
      else std::printf("%lld\n", static_cast<long long>(id));
    });
    if (count_only) {
      if (json) print_json({{"count", n}});
      else std::printf("%lld\n", static_cast<long long>(n));
    }
    store.report(m);
    return 0;
  }
  auto ll = [](Id v) { return static_cast<long long>(v); };
  if (cmd.given(o_node) || cmd.given(o_nodes)) {
    const auto [a, b] = cmd.given(o_node) ? parse_range("--node", node) : parse_range("--nodes", nodes);
    m.check_node_range(a, b);
    auto print = [&](Id id, const Vec3& p) {
      if (json) print_json({{"id", id}, {"xyz", {p.x, p.y, p.z}}});
      else std::printf("node %lld  %.17g %.17g %.17g\n", ll(id), p.x, p.y, p.z);
    };
    if (b - a <= kFewIds) {
      MeshCursor mc;
      for (Id id = a; id < b; ++id) print(id, m.node(id, mc));
    } else {
      NodeCursor cur(m, a, b);
      Id id;
      Vec3 p;
      while (cur.next(id, p)) print(id, p);
    }
    store.report(m);
    return 0;
  }
  const auto [a, b] = cmd.given(o_element) ? parse_range("--element", element) : parse_range("--elements", elements);
  m.check_element_range(a, b);
  std::unique_ptr<ElementCursor> cur;
  if (b - a > kFewIds) cur = std::make_unique<ElementCursor>(m, a, b);
  MeshCursor mc;
  Id next = a;
  FineElement el;
  const bool vol = m.mode() == Mode::Volume;
  while (cur ? cur->next(el) : next < b && (el = m.element(next++, mc), true)) {
    const Id block = m.info().blocks.at(static_cast<size_t>(el.block)).id;
    if (json) {
      Json nodes_json = Json::array(), ijk = Json::array();
      for (int q = 0; q < el.num_nodes; ++q) nodes_json.push_back(el.nodes[q]);
      for (int d = 0; d < (vol ? 3 : 2); ++d) ijk.push_back(el.ijk[d]);
      print_json({{"id", el.id}, {"nodes", nodes_json}, {"block", block}, {"coarse_element", el.coarse_element}, {"ijk", ijk}});
    } else {
      std::string nodes_text;
      for (int q = 0; q < el.num_nodes; ++q) nodes_text += (q ? "," : "") + std::to_string(el.nodes[q]);
      std::string ijk = std::to_string(el.ijk[0]) + "," + std::to_string(el.ijk[1]);
      if (vol) ijk += "," + std::to_string(el.ijk[2]);
      std::printf("element %lld  nodes %s  block %lld  coarse element %lld  ijk %s\n", ll(el.id), nodes_text.c_str(),
                  ll(block), ll(el.coarse_element), ijk.c_str());
    }
  }
  store.report(m);
  return 0;
}

}  // namespace

// Under mpirun, --box --count is counted by every rank on its chunk (errors
// agreed before the sum); every other query runs on rank 0.
int cmd_query(const std::vector<std::string>& argv) {
  mpi::Session& mpi = session();
  const std::vector<std::string> options = options_part(argv);
  const bool has_box = std::find(options.begin(), options.end(), "--box") != options.end() ||
                       std::any_of(options.begin(), options.end(), [](const std::string& a) { return a.rfind("--box=", 0) == 0; });
  const bool has_count = std::find(options.begin(), options.end(), "--count") != options.end();
  if (!mpi.active() || !(has_box && has_count)) return on_rank0([&] { return query(argv); });
  long long mine = 0, sum = 0;
  bool json = false;
  std::pair<std::string, std::string> opened;
  agree([&] { query(argv, &mine, &json, &opened); });
  check_same_store(opened.first, opened.second);
  MPI_Reduce(&mine, &sum, 1, MPI_LONG_LONG, MPI_SUM, 0, mpi.comm());
  if (mpi.rank() == 0) {
    if (json) print_json({{"count", sum}});
    else std::printf("%lld\n", sum);
  }
  return 0;
}

}  // namespace dicer::cli
