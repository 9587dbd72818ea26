// The store file: write (temp + rename) and read back (see FORMAT.md).
#include "dicer/store.hpp"

#include <unistd.h>

#include <filesystem>

#include "dicer/error.hpp"
#include "hdf5_file.hpp"

namespace dicer {
namespace {

// Strings of a list as one char array plus offsets (fixed types, chunkable).
void write_strings(h5::File& f, const std::string& base, const std::vector<std::string>& names) {
  std::vector<char> chars;
  std::vector<std::int64_t> off{0};
  for (const auto& s : names) {
    chars.insert(chars.end(), s.begin(), s.end());
    off.push_back(static_cast<std::int64_t>(chars.size()));
  }
  f.write(base + "_chars", chars);
  f.write(base + "_offset", off);
}

std::vector<std::string> read_strings(const h5::File& f, const std::string& base, size_t count) {
  const auto chars = f.read<char>(base + "_chars");
  const auto off = f.read<std::int64_t>(base + "_offset");
  if (off.size() != count + 1 || off.front() != 0 || off.back() != static_cast<std::int64_t>(chars.size()))
    throw Error(ErrorKind::Corrupt, f.path() + ": " + base + "_offset is inconsistent");
  std::vector<std::string> out;
  for (size_t i = 0; i < count; ++i) {
    if (off[i + 1] < off[i]) throw Error(ErrorKind::Corrupt, f.path() + ": " + base + "_offset is not increasing");
    out.emplace_back(chars.begin() + off[i], chars.begin() + off[i + 1]);
  }
  return out;
}

template <class T>
void expect_equal(const h5::File& f, const std::string& name, const std::vector<T>& rebuilt, std::uint64_t cols = 1) {
  if (f.read<T>(name, cols) != rebuilt)
    throw Error(ErrorKind::Corrupt, f.path() + ": dataset " + name +
                                        " does not match the topology rebuilt from the stored coarse mesh");
}

}  // namespace

void write_store(const FineMesh& mesh, const std::string& path) {
  namespace fs = std::filesystem;
  const fs::path final_path(path);
  const fs::path dir = final_path.has_parent_path() ? final_path.parent_path() : fs::path(".");
  const fs::path tmp = dir / ("." + final_path.filename().string() + ".tmp-" + std::to_string(::getpid()));
  try {
    {
      h5::File f = h5::File::create(tmp.string());
      const CoarseMesh& c = mesh.coarse();
      const Topology& t = mesh.topology();
      f.write_attr("format", std::string(kStoreFormatName));
      f.write_attr("format_version", kStoreFormatVersion);
      f.write_attr("mode", std::string(mode_name(c.mode)));
      f.write_attr("source", c.source);
      f.group("coarse");
      f.write("coarse/x", c.x), f.write("coarse/y", c.y), f.write("coarse/z", c.z);
      f.write("coarse/vertex_file_id", c.vertex_file_id);
      f.write("coarse/conn", c.conn, static_cast<std::uint64_t>(c.corners_per_element()));
      f.write("coarse/element_file_id", c.element_file_id);
      f.write("coarse/element_block", c.element_block);
      f.write("coarse/vertex_geo_dim", c.vertex_geo_dim);
      f.write("coarse/vertex_geo_tag", c.vertex_geo_tag);
      std::vector<std::int64_t> block_id;
      std::vector<std::string> block_name;
      for (const auto& b : c.blocks) block_id.push_back(b.id), block_name.push_back(b.name);
      f.write("coarse/block_id", block_id);
      write_strings(f, "coarse/block_name", block_name);
      // Side and node sets: ids, names, CSR offsets, members.
      std::vector<std::int64_t> ss_id, ss_off{0}, ss_elem;
      std::vector<std::int8_t> ss_side;
      std::vector<std::string> ss_name;
      for (const auto& s : c.side_sets) {
        ss_id.push_back(s.id), ss_name.push_back(s.name);
        ss_elem.insert(ss_elem.end(), s.element.begin(), s.element.end());
        ss_side.insert(ss_side.end(), s.side.begin(), s.side.end());
        ss_off.push_back(static_cast<std::int64_t>(ss_elem.size()));
      }
      f.write("coarse/side_set_id", ss_id), f.write("coarse/side_set_offset", ss_off);
      f.write("coarse/side_set_element", ss_elem), f.write("coarse/side_set_side", ss_side);
      write_strings(f, "coarse/side_set_name", ss_name);
      std::vector<std::int64_t> ns_id, ns_off{0}, ns_vert;
      std::vector<std::string> ns_name;
      for (const auto& s : c.node_sets) {
        ns_id.push_back(s.id), ns_name.push_back(s.name);
        ns_vert.insert(ns_vert.end(), s.vertex.begin(), s.vertex.end());
        ns_off.push_back(static_cast<std::int64_t>(ns_vert.size()));
      }
      f.write("coarse/node_set_id", ns_id), f.write("coarse/node_set_offset", ns_off);
      f.write("coarse/node_set_vertex", ns_vert);
      write_strings(f, "coarse/node_set_name", ns_name);

      f.group("topology");
      f.write("topology/edge_v", t.edge_v, 2);
      f.write("topology/face_v", t.face_v, 4);
      f.write("topology/face_edge", t.face_edge, 4);
      f.write("topology/face_edge_rev", t.face_edge_rev, 4);
      f.write("topology/face_elem", t.face_elem, 2);
      f.write("topology/elem_edge", t.elem_edge, static_cast<std::uint64_t>(t.edges_per_element()));
      f.write("topology/elem_edge_rev", t.elem_edge_rev, static_cast<std::uint64_t>(t.edges_per_element()));
      f.write("topology/elem_face", t.elem_face, static_cast<std::uint64_t>(t.faces_per_element()));
      f.write("topology/elem_face_code", t.elem_face_code, static_cast<std::uint64_t>(t.faces_per_element()));

      f.group("sheets");
      const Sheets sheets = find_sheets(c, t);
      f.write("sheets/edge_sheet", sheets.edge_sheet);
      f.write("sheets/sheet_interval", mesh.sheet_intervals());
      f.group("geometry");  // bounding fine arrays: empty until geometry-conforming dicing
      f.write("geometry/bounding_xyz", std::vector<double>{}, 3);
    }
    fs::rename(tmp, final_path);
  } catch (...) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw;
  }
}

FineMesh read_store(const std::string& path) {
  h5::File f = h5::File::open_read(path);
  if (!f.exists("/") || f.read_attr_string("format") != kStoreFormatName)
    throw Error(ErrorKind::BadInput, path + ": not a dicer store (format attribute missing or wrong)");
  const std::int64_t version = f.read_attr_int("format_version");
  if (version != kStoreFormatVersion)
    throw Error(ErrorKind::Unsupported, path + ": store format version " + std::to_string(version) +
                                            " is not known to this dicer (it reads version " +
                                            std::to_string(kStoreFormatVersion) + ")");
  CoarseMesh c;
  c.source = f.read_attr_string("source");
  const std::string mode = f.read_attr_string("mode");
  if (mode != "volume" && mode != "surface") throw Error(ErrorKind::Corrupt, path + ": unknown mode \"" + mode + "\"");
  c.mode = mode == "volume" ? Mode::Volume : Mode::Surface;
  c.x = f.read<double>("coarse/x"), c.y = f.read<double>("coarse/y"), c.z = f.read<double>("coarse/z");
  c.vertex_file_id = f.read<std::int64_t>("coarse/vertex_file_id");
  c.conn = f.read<std::int64_t>("coarse/conn", static_cast<std::uint64_t>(c.corners_per_element()));
  c.element_file_id = f.read<std::int64_t>("coarse/element_file_id");
  c.element_block = f.read<std::int32_t>("coarse/element_block");
  c.vertex_geo_dim = f.read<std::int8_t>("coarse/vertex_geo_dim");
  c.vertex_geo_tag = f.read<std::int32_t>("coarse/vertex_geo_tag");
  const auto block_id = f.read<std::int64_t>("coarse/block_id");
  const auto block_name = read_strings(f, "coarse/block_name", block_id.size());
  for (size_t b = 0; b < block_id.size(); ++b) c.blocks.push_back({block_id[b], block_name[b]});
  {
    const auto id = f.read<std::int64_t>("coarse/side_set_id");
    const auto off = f.read<std::int64_t>("coarse/side_set_offset");
    const auto el = f.read<std::int64_t>("coarse/side_set_element");
    const auto sd = f.read<std::int8_t>("coarse/side_set_side");
    const auto names = read_strings(f, "coarse/side_set_name", id.size());
    if (off.size() != id.size() + 1 || el.size() != sd.size() || off.back() != static_cast<std::int64_t>(el.size()))
      throw Error(ErrorKind::Corrupt, path + ": side set arrays are inconsistent");
    for (size_t s = 0; s < id.size(); ++s) {
      if (off[s] > off[s + 1] || off[s] < 0) throw Error(ErrorKind::Corrupt, path + ": side set offsets");
      c.side_sets.push_back({id[s], names[s], {el.begin() + off[s], el.begin() + off[s + 1]},
                             {sd.begin() + off[s], sd.begin() + off[s + 1]}});
    }
  }
  {
    const auto id = f.read<std::int64_t>("coarse/node_set_id");
    const auto off = f.read<std::int64_t>("coarse/node_set_offset");
    const auto vs = f.read<std::int64_t>("coarse/node_set_vertex");
    const auto names = read_strings(f, "coarse/node_set_name", id.size());
    if (off.size() != id.size() + 1 || off.back() != static_cast<std::int64_t>(vs.size()))
      throw Error(ErrorKind::Corrupt, path + ": node set arrays are inconsistent");
    for (size_t s = 0; s < id.size(); ++s) {
      if (off[s] > off[s + 1] || off[s] < 0) throw Error(ErrorKind::Corrupt, path + ": node set offsets");
      c.node_sets.push_back({id[s], names[s], {vs.begin() + off[s], vs.begin() + off[s + 1]}});
    }
  }
  for (const auto& ns : c.node_sets)
    for (Id v : ns.vertex)
      if (v < 0 || v >= c.num_vertices()) throw Error(ErrorKind::Corrupt, path + ": node set entry out of range");
  // The stored mesh passed validation when it was written; checking again
  // costs O(n log n) and turns a tampered file into an error, not a crash.
  try {
    const size_t nv = c.x.size();
    validate_coarse_mesh(c);
    if (c.x.size() != nv || !c.warnings.empty())
      throw Error(ErrorKind::Corrupt, "stored coarse mesh was modified by validation");
  } catch (const Error& e) {
    throw Error(ErrorKind::Corrupt, path + ": stored coarse mesh is invalid: " + e.what());
  }
  Topology t = build_topology(c);
  expect_equal(f, "topology/edge_v", t.edge_v, 2);
  expect_equal(f, "topology/face_v", t.face_v, 4);
  expect_equal(f, "topology/elem_edge", t.elem_edge, static_cast<std::uint64_t>(t.edges_per_element()));
  expect_equal(f, "topology/elem_face_code", t.elem_face_code, static_cast<std::uint64_t>(t.faces_per_element()));
  const Sheets sheets = find_sheets(c, t);
  expect_equal(f, "sheets/edge_sheet", sheets.edge_sheet);
  auto sheet_interval = f.read<std::int64_t>("sheets/sheet_interval");
  if (static_cast<Id>(sheet_interval.size()) != sheets.num_sheets())
    throw Error(ErrorKind::Corrupt, path + ": sheets/sheet_interval has " + std::to_string(sheet_interval.size()) +
                                        " entries for " + std::to_string(sheets.num_sheets()) + " sheets");
  for (Id n : sheet_interval)
    if (n < 1) throw Error(ErrorKind::Corrupt, path + ": sheets/sheet_interval holds an interval < 1");
  IntervalPlan plan{sheet_interval, {}};
  Numbering num(t, edge_intervals(sheets, plan));
  return FineMesh(std::move(c), std::move(t), std::move(num), std::move(sheet_interval));
}

StoreSummary store_summary(const std::string& path) {
  h5::File f = h5::File::open_read(path);
  StoreSummary s;
  s.format_version = static_cast<int>(f.read_attr_int("format_version"));
  std::error_code ec;
  s.file_bytes = std::filesystem::file_size(path, ec);
  return s;
}

}  // namespace dicer
