// dicer query: fine nodes and elements by id.
#include <algorithm>
#include <cstdio>

#include "command.hpp"
#include "common.hpp"
#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/fine_mesh.hpp"
#include "json_out.hpp"

namespace dicer::cli {

static const CommandDoc kDoc = {
    "query",
    R"(query STORE (--node ID | --nodes FIRST:END | --element ID |
                   --elements FIRST:END | --box x0,y0,z0,x1,y1,z1 [--count])
                   [--json] [store options])",
    R"(Regenerates fine nodes or elements by id; ids start at 0. Ranges are
half-open: --nodes 1000:2000 prints ids 1000..1999, one line each. Give
exactly one of --node, --nodes, --element, --elements, --box.

Node ids (store format 6, owner order): coarse element by coarse element
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
)"};

namespace {

// `chunk_count`: under mpirun with --box --count, this rank's count in its
// chunk is stored there and nothing is printed (the caller sums).
int query(const std::vector<std::string>& argv, long long* chunk_count = nullptr, bool* as_json = nullptr) {
  Command cmd(kDoc);
  std::string path, node, nodes, element, elements, box_text;
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
                          "axis-aligned box (one per line); coarse elements "
                          "whose bounding box misses it are skipped unread");
  auto* o_count = cmd.flag("--count", count_only, "with --box: only the number of such elements");
  cmd.flag("--json", json,
           "one JSON object per line:\n"
           "node:    {\"id\":..., \"xyz\":[x,y,z]}\n"
           "element: {\"id\":..., \"nodes\":[8 ids], \"block\":...,\n"
           "          \"coarse_element\":..., \"ijk\":[i,j,k]}\n"
           "          (surface meshes: 4 node ids and [i,j])\n"
           "box:     {\"id\":...} per element, or {\"count\":...}");
  StoreFlags store(cmd);
  if (!cmd.parse(argv)) return 0;
  const int chosen = cmd.given(o_node) + cmd.given(o_nodes) + cmd.given(o_element) + cmd.given(o_elements) + cmd.given(o_box);
  if (chosen != 1) throw Error(ErrorKind::Usage, "give exactly one of --node, --nodes, --element, --elements, --box");
  if (cmd.given(o_count) && !cmd.given(o_box)) throw Error(ErrorKind::Usage, "--count goes with --box");

  const FineMesh m = read_store(path, store.options());
  if (cmd.given(o_box)) {
    const Box box = parse_box(box_text);
    if (chunk_count && count_only) {  // rank r counts in chunk r
      mpi::Session& mpi = session();
      const ChunkRange r = plan_chunks(m, mpi.size())[static_cast<size_t>(mpi.rank())];
      *chunk_count = for_each_in_box(m, box, {}, r.first_coarse, r.end_coarse);
      if (as_json) *as_json = json;
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
    if (a < 0 || b > m.num_nodes())
      throw Error(ErrorKind::Usage, "node ids " + std::to_string(a) + ".." + std::to_string(b - 1) +
                                        " out of range (the mesh has " + std::to_string(m.num_nodes()) + " nodes, ids 0.." +
                                        std::to_string(m.num_nodes() - 1) + ")");
    NodeCursor cur(m, a, b);
    Id id;
    Vec3 p;
    while (cur.next(id, p)) {
      if (json) print_json({{"id", id}, {"xyz", {p.x, p.y, p.z}}});
      else std::printf("node %lld  %.17g %.17g %.17g\n", ll(id), p.x, p.y, p.z);
    }
    store.report(m);
    return 0;
  }
  const auto [a, b] = cmd.given(o_element) ? parse_range("--element", element) : parse_range("--elements", elements);
  if (a < 0 || b > m.num_elements())
    throw Error(ErrorKind::Usage, "element ids " + std::to_string(a) + ".." + std::to_string(b - 1) +
                                      " out of range (the mesh has " + std::to_string(m.num_elements()) +
                                      " elements, ids 0.." + std::to_string(m.num_elements() - 1) + ")");
  ElementCursor cur(m, a, b);
  FineElement el;
  const bool vol = m.mode() == Mode::Volume;
  while (cur.next(el)) {
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
  const bool has_box = std::find(argv.begin(), argv.end(), "--box") != argv.end() ||
                       std::any_of(argv.begin(), argv.end(), [](const std::string& a) { return a.rfind("--box=", 0) == 0; });
  const bool has_count = std::find(argv.begin(), argv.end(), "--count") != argv.end();
  if (!mpi.active() || !(has_box && has_count)) return on_rank0([&] { return query(argv); });
  long long mine = 0, sum = 0;
  bool json = false;
  agree([&] { query(argv, &mine, &json); });
  MPI_Reduce(&mine, &sum, 1, MPI_LONG_LONG, MPI_SUM, 0, mpi.comm());
  if (mpi.rank() == 0) {
    if (json) print_json({{"count", sum}});
    else std::printf("%lld\n", sum);
  }
  return 0;
}

}  // namespace dicer::cli
