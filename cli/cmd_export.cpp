// dicer export: a chunk, a box or the whole mesh to VTKHDF, MSH 4.1 or Exodus II.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>

#include "dicer/mpi.hpp"

#include "command.hpp"
#include "common.hpp"
#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/partition.hpp"
#include "dicer/store.hpp"

namespace dicer::cli {

static const CommandDoc kDoc = {
    "export",
    R"(export STORE [--format FMT] -o OUT [--chunk K/N | --chunks N [--nemesis]]
                    [--box x0,y0,z0,x1,y1,z1] [--deflate LEVEL] [--quiet] [store options])",
    R"(Writes fine elements for a solver or viewer, generated on the fly from the
store and written as they are generated: memory is the store's cache budget
plus a few MiB, ~20 B per coarse element and one coarse element's slab of
grid planes with its boundary (O(interval^2): ~0.5 GiB at interval 2,000),
whatever the fine mesh's size. Held in memory: a --box selection (about
120 B per kept element) and, for msh and exodus, the side-set faces (9 B
each). What cannot fit is refused up front by name (exit 2).

Formats:
  vtkhdf      VTKHDF UnstructuredGrid 1.0 (ParaView 5.10+, no plugin), one
              partition per chunk; point data GlobalNodeId, cell data
              GlobalElementId and BlockId; uncompressed unless --deflate
  msh         Gmsh MSH 4.1 binary (msh-ascii: ASCII); an entity and a
              physical group per block, boundary elements per side set;
              chunk files merge in Gmsh; no node sets (the format has none)
  exodus      Exodus II: element blocks with names, side and node sets
              carried to the fine mesh, global id maps (1-based); with
              --chunks N --nemesis, N files OUT.N.r decomposed the Nemesis
              way for a parallel solver (global parameters, load balance,
              node communication maps), as N MPI ranks of dicer export write

Without --format, OUT's extension says which: .vtkhdf or .hdf, .msh (binary),
.e, .exo, .ex2 or .g (Exodus); any other needs --format.

A chunk K of N is a contiguous range of coarse elements (in the store's
order) holding ~1/N of the fine elements; nodes shared with other chunks
keep their global ids and identical coordinates. OUT is written under a
temporary name in its folder and renamed when complete: Ctrl-C, SIGTERM
and SIGHUP (exit 130, 143, 129) leave nothing behind. The N files of
--nemesis are renamed together once all are written.

Under mpirun with P ranks, rank r writes chunk r of P (no --chunk, --chunks
or --box): vtkhdf one file of P partitions (parallel HDF5), exodus the
Nemesis files OUT.P.r, msh the files OUT.P.r.
)",
    R"(dicer export fine.dice.h5 -o fine.vtkhdf                  # the format from the extension
dicer export fine.dice.h5 --format exodus --chunk 3/16 -o part3.exo
dicer export fine.dice.h5 --format exodus --chunks 8 --nemesis -o fine.e   # fine.e.8.0 .. fine.e.8.7
dicer export fine.dice.h5 --format msh --box 0,0,0,1,1,0.5 -o cut.msh --stats
dicer export fine.dice.h5 --format vtkhdf --deflate 1 -o small.vtkhdf   # 4-5x smaller, slower
)"};

namespace {

constexpr const char* kFormats = "vtkhdf, msh, msh-ascii or exodus";

// --format, or else the one OUT's extension names (kDoc).
std::string format_of(const std::string& format, bool given, const std::string& out) {
  if (!given) {
    const std::string ext = std::filesystem::path(out).extension().string();
    if (ext == ".vtkhdf" || ext == ".hdf") return "vtkhdf";
    if (ext == ".msh") return "msh";
    if (ext == ".e" || ext == ".exo" || ext == ".ex2" || ext == ".g") return "exodus";
    throw Error(ErrorKind::Usage, std::string("missing --format FMT (") + kFormats + "): " +
                                      (ext.empty() ? "OUT has no extension" : "OUT's extension " + ext + " names none"));
  }
  if (format != "vtkhdf" && format != "msh" && format != "msh-ascii" && format != "exodus")
    throw Error(ErrorKind::Usage, "--format: \"" + format + "\" is not one of " + kFormats);
  return format;
}

// The sets of the store `m` was read from: read_store_sets checks its uuid,
// so a store replaced at `path` since (a re-dice) is Error{Io}, not mixed in.
MeshSets sets_of(const FineMesh& m, const std::string& path) {
  StoreSets s = read_store_sets(m, path);
  MeshSets sets;
  sets.side_sets = std::move(s.side_sets);
  sets.node_sets = std::move(s.node_sets);
  return sets;
}

// What an MSH export leaves out is said, even under --quiet (data left
// out, not progress); Exodus keeps it: sides MSH has no element for (a
// shell's face sides: msh_writes_side), and node sets (MSH has none).
void note_what_msh_leaves_out(const FineMesh& m, const MeshSets& sets) {
  for (const auto& set : sets.side_sets) {
    const auto faces = std::count_if(set.side.begin(), set.side.end(),
                                     [&](std::int8_t k) { return !msh_writes_side(m.mode(), k); });
    if (faces > 0)
      std::fprintf(stderr, "dicer export: note: side set %lld: the face sides of %lld coarse shells (the quads "
                           "themselves) are not written to MSH, which has no element for them; Exodus keeps them\n",
                   static_cast<long long>(set.id), static_cast<long long>(faces));
  }
  std::string ids;
  for (const auto& set : sets.node_sets)
    if (!set.vertex.empty()) ids += (ids.empty() ? "" : ", ") + std::to_string(set.id);
  if (!ids.empty())
    std::fprintf(stderr, "dicer export: note: node sets %s are not written to MSH, which has no node sets; Exodus "
                         "keeps them\n", ids.c_str());
  // Group 0 is written unnamed (export/msh.cpp: Gmsh would put its name on group 1).
  auto unnamed = [](const char* what, const std::string& name) {
    if (!name.empty())
      std::fprintf(stderr, "dicer export: note: the name of %s 0 (\"%s\") is not written to MSH, where Gmsh would "
                           "give it to group 1; the group is written as physical group 0; Exodus keeps the name\n",
                   what, printable(name).c_str());
  };
  for (const auto& b : m.info().blocks)
    if (b.id == 0) unnamed("block", b.name);
  for (const auto& set : sets.side_sets)
    if (set.id == 0) unnamed("side set", set.name);
}

// Under mpirun -n P: rank r exports chunk r of P. Exodus: the Nemesis file
// OUT.P.r (communication maps exchanged between ranks); VTKHDF: one file,
// written collectively; MSH: OUT.P.r. The same files as one process with
// --chunks P (and --nemesis).
int export_ranks(const std::string& path, const std::string& out, const std::string& format, int deflate, bool quiet,
                 const StoreFlags& store) {
  mpi::Session& mpi = session();
  const int P = mpi.size(), r = mpi.rank();
  std::optional<FineMesh> mesh;
  MeshSets sets;
  std::vector<ChunkRange> plan;
  agree([&] {
    mesh.emplace(read_store(path, store.options()));
    sets = sets_of(*mesh, path);
    plan = plan_chunks(*mesh, P);
  });
  check_same_store(path, mesh->info().uuid);
  const FineMesh& m = *mesh;
  if (r == 0 && format != "vtkhdf" && format != "exodus") note_what_msh_leaves_out(m, sets);
  const CancelOnSignals cancel_on_signals;
  long long counts[2] = {0, 0}, totals[2] = {0, 0};
  if (format != "vtkhdf")
    agree([&] { check_output_file(nemesis_path(out, P, r), "-o", {{path, "STORE"}}); });
  // The ranks' files appear together or not at all: each is written
  // uncommitted (PendingFile), and committed once every rank has written.
  PendingFile pending;
  const std::string nothing_written =
      "nothing written to " + (format == "vtkhdf" ? out
                                                  : nemesis_path(out, P, 0) + (P > 1 ? " ... " + nemesis_path(out, P, P - 1) : ""));
  try {
    if (format == "exodus") {
      const std::vector<NodeRun> sharing = mpi::exchange_sharing(mpi.comm(), m, plan);
      agree([&] {
        const ChunkStream c(m, plan[static_cast<size_t>(r)], sets, {}, cancel_requested);
        const NemesisInfo info = nemesis_info(c, P, r, sharing, global_set_counts(m, sets));
        write_exodus(c, nemesis_path(out, P, r), &info, &pending);
        counts[0] = c.num_elements(), counts[1] = c.num_nodes();
      });
    } else {
      std::optional<ChunkStream> c;
      agree([&] {
        // VTKHDF writes no sets: none are gathered (a side set holds 9 bytes a fine face).
        c.emplace(m, plan[static_cast<size_t>(r)], format == "vtkhdf" ? MeshSets{} : sets, std::function<void(Id, Id)>{},
                  cancel_requested);
        counts[0] = c->num_elements(), counts[1] = c->num_nodes();
        if (format != "vtkhdf") write_msh(*c, nemesis_path(out, P, r), format == "msh", &pending);
      });
      if (format == "vtkhdf") mpi::write_vtkhdf_collective(mpi.comm(), *c, out, deflate);
    }
    if (pending) agree([&] { throw_if_cancelled(nothing_written); });
  } catch (const Error&) {
    // As one process says it: the signal, and that nothing was written.
    throw_if_cancelled(nothing_written);
    throw;
  }
  if (pending) {
    agree([&] { pending->flush(); });  // every rank's before the first rename
    agree([&] {
      try {
        pending->commit();
      } catch (const Error& e) {
        // The other ranks rename theirs meanwhile: say what the set holds.
        if (P == 1) throw;
        throw Error(e.kind(), std::string(e.what()) + "; the other ranks' pieces of " + out + "." + std::to_string(P) +
                                  ".* may be replaced already: the set may mix new and old pieces (export again)");
      }
    });
  }
  MPI_Reduce(counts, totals, 2, MPI_LONG_LONG, MPI_SUM, 0, mpi.comm());
  if (r == 0 && !quiet)
    std::printf("exported %s: %lld fine elements, %lld nodes (shared ones once per rank) from %d %s to %s%s\n",
                printable(path).c_str(), totals[0], totals[1], P, P == 1 ? "rank" : "ranks", printable(out).c_str(),
                format == "vtkhdf" ? "" : (" (" + printable(nemesis_path(out, P, 0)) + " ...)").c_str());
  store.report(m);
  return 0;
}

}  // namespace

int cmd_export(const std::vector<std::string>& argv) {
  Command cmd(kDoc);
  std::string path, out, format, chunk, chunks, box_text;
  bool quiet = false;
  cmd.input("STORE", path, "the store to export");
  cmd.output(out, "OUT", "the file to write");
  auto* o_format = cmd.value("--format", format, "FMT", "vtkhdf, msh, msh-ascii or exodus (see Formats above)",
                             "Options", "from OUT's extension");
  auto* o_chunk = cmd.value("--chunk", chunk, "K/N", "chunk K (0-based) of N", "Options", "the whole mesh");
  auto* o_chunks = cmd.value("--chunks", chunks, "N",
                             "vtkhdf: the whole mesh as N partitions of one file; exodus with --nemesis: N files",
                             "Options", "about 4M fine elements per partition");
  bool nemesis = false;
  cmd.flag("--nemesis", nemesis, "exodus with --chunks N: one Nemesis file per chunk, OUT.N.r");
  auto* o_box = cmd.value("--box", box_text, "x0,y0,z0,x1,y1,z1", "only the elements whose centroid is in the box (vtkhdf with --chunks N: N partitions, the box's part of each chunk)");
  std::string deflate_text;
  auto* o_deflate = cmd.value("--deflate", deflate_text, "LEVEL",
                              "vtkhdf: byte shuffle + deflate at LEVEL (1 fastest .. 9 smallest) on every dataset",
                              "Options", "0: no compression, the fastest to write and read");
  cmd.flag("--quiet", quiet, "no progress bar, no summary on stdout");
  StoreFlags store(cmd);
  int deflate = 0;
  auto parse_deflate = [&] {
    if (!cmd.given(o_deflate)) return;
    if (format != "vtkhdf") throw Error(ErrorKind::Usage, "--deflate is for --format vtkhdf");
    const Id level = parse_int("--deflate", deflate_text);
    if (level < 0 || level > 9) throw Error(ErrorKind::Usage, "--deflate " + deflate_text + ": need a level 0..9");
    deflate = static_cast<int>(level);
  };
  mpi::Session& mpi = session();
  if (mpi.active()) {
    bool run = true;
    agree([&] {
      run = cmd.parse(argv);
      if (!run) return;
      format = format_of(format, cmd.given(o_format), out);
      parse_deflate();
      if (cmd.given(o_chunk) || cmd.given(o_chunks) || cmd.given(o_box))
        throw Error(ErrorKind::Usage, "under mpirun every rank exports its chunk of the whole mesh: no --chunk, "
                                      "--chunks or --box (run without mpirun for those)");
    });
    return run ? export_ranks(path, out, format, deflate, quiet, store) : 0;
  }
  if (!cmd.parse(argv)) return 0;
  format = format_of(format, cmd.given(o_format), out);
  parse_deflate();
  std::optional<Box> box;
  if (cmd.given(o_box)) box = parse_box(box_text);
  if (cmd.given(o_chunk) && cmd.given(o_chunks)) throw Error(ErrorKind::Usage, "give --chunk K/N or --chunks N, not both");
  if (nemesis && (format != "exodus" || !cmd.given(o_chunks) || box))
    throw Error(ErrorKind::Usage, "--nemesis goes with --format exodus --chunks N (and no --box)");
  if (cmd.given(o_chunks) && format != "vtkhdf" && !nemesis)
    throw Error(ErrorKind::Usage, "--chunks N is for --format vtkhdf, or exodus with --nemesis");

  const FineMesh m = read_store(path, store.options());
  MeshSets sets = sets_of(m, path);
  if (format == "msh" || format == "msh-ascii") note_what_msh_leaves_out(m, sets);
  std::vector<ChunkRange> ranges;
  if (cmd.given(o_chunk)) {
    const auto slash = chunk.find('/');
    if (slash == std::string::npos || chunk.find('/', slash + 1) != std::string::npos)
      throw Error(ErrorKind::Usage, "--chunk: \"" + chunk + "\" is not K/N");
    const Id k = parse_int("--chunk", chunk.substr(0, slash)), n = parse_int("--chunk", chunk.substr(slash + 1));
    if (n < 1 || k < 0 || k >= n)
      throw Error(ErrorKind::Usage, "--chunk " + chunk + ": need 0 <= K < N (chunks are numbered from 0)");
    if (n > m.num_coarse_elements())
      throw Error(ErrorKind::Usage, "--chunk " + chunk + ": the mesh has only " + std::to_string(m.num_coarse_elements()) +
                                        " coarse elements, so at most that many chunks");
    ranges.push_back(plan_chunks(m, n)[static_cast<size_t>(k)]);
  } else if ((format == "vtkhdf" && (!box || cmd.given(o_chunks))) || nemesis) {
    Id n = cmd.given(o_chunks) ? parse_int("--chunks", chunks)
                               : std::max<Id>(1, (m.num_elements() + (Id{1} << 22) - 1) >> 22);
    if (n < 1) throw Error(ErrorKind::Usage, "--chunks must be at least 1");
    if (cmd.given(o_chunks) && n > std::max<Id>(1, m.num_coarse_elements()))
      throw Error(ErrorKind::Usage, "--chunks " + chunks + ": the mesh has only " +
                                        std::to_string(m.num_coarse_elements()) +
                                        " coarse elements, so at most that many chunks");
    n = std::min(n, std::max<Id>(1, m.num_coarse_elements()));
    ranges = plan_chunks(m, n);
    // The files written are OUT.N.r, not OUT: each must not be an input.
    if (nemesis)
      for (Id r = 0; r < n; ++r) check_output_file(nemesis_path(out, n, r), "-o", {{path, "STORE"}});
  } else {
    ranges.push_back(ChunkRange{0, 1, 0, m.num_coarse_elements(), m.num_elements()});
  }

  const CancelOnSignals cancel_on_signals;
  const Id files = static_cast<Id>(ranges.size());
  const std::string nothing_written =
      "nothing written to " + (nemesis ? nemesis_path(out, files, 0) + (files > 1 ? " ... " + nemesis_path(out, files, files - 1) : "")
                                       : out);
  Id total_coarse = 0;
  for (const auto& r : ranges) total_coarse += r.end_coarse - r.first_coarse;
  Progress bar("export", total_coarse, quiet);
  Id done_before = 0;
  Id written_elements = 0, written_nodes = 0;
  try {
    // Chunk r's share of the bar: its coarse elements, scaled by the
    // fraction of its passes done.
    auto progress_of = [&](const ChunkRange& r) {
      const Id span = r.end_coarse - r.first_coarse;
      return [&bar, &done_before, span](Id done, Id total) {
        bar.update(done_before + (total > 0 ? static_cast<Id>(static_cast<double>(span) * done / total) : 0));
      };
    };
    auto finished = [&](const ChunkRange& r, const ChunkSource& c) {
      throw_if_cancelled(nothing_written);
      done_before += r.end_coarse - r.first_coarse;
      bar.update(done_before);
      written_elements += c.num_elements(), written_nodes += c.num_nodes();
    };
    // A box keeps an unknown part of the chunk: held in memory.
    auto boxed = [&](const ChunkRange& r) {
      auto c = std::make_unique<ExportChunk>(m, r, box);
      c->prepare(sets, progress_of(r), cancel_requested);
      return c;
    };
    if (nemesis) {
      // Committed together once all are written (PendingFile).
      const auto sharing = in_process_sharing(m, ranges);
      const SetCounts counts = global_set_counts(m, sets);
      std::vector<PendingFile> pieces(ranges.size());
      for (const auto& r : ranges) {
        const ChunkStream c(m, r, sets, progress_of(r), cancel_requested);
        const NemesisInfo info = nemesis_info(c, r.count, r.index, sharing[static_cast<size_t>(r.index)], counts);
        write_exodus(c, nemesis_path(out, r.count, r.index), &info, &pieces[static_cast<size_t>(r.index)]);
        finished(r, c);
      }
      for (auto& f : pieces) f->flush();  // all flushed before the first rename (AtomicOutput::flush)
      for (size_t k = 0; k < pieces.size(); ++k) {
        try {
          pieces[k]->commit();
        } catch (const Error& e) {
          if (k == 0) throw;
          // Everything was flushed first: what fails here is a rename (or
          // opening the folder again), after pieces 0..k-1 were renamed.
          const Id n = static_cast<Id>(pieces.size());
          const std::string done = k == 1 ? "piece " + nemesis_path(out, n, 0) + " was"
                                          : "pieces " + nemesis_path(out, n, 0) + " to " +
                                                nemesis_path(out, n, static_cast<Id>(k) - 1) + " were";
          throw Error(e.kind(), std::string(e.what()) + "; " + done +
                                    " replaced already: the set mixes new and old pieces (export again)");
        }
      }
    } else if (format == "vtkhdf") {
      // VTKHDF writes no sets: none are gathered (a side set holds 9 bytes a fine face).
      sets = MeshSets{};
      VtkHdfWriter w(out, static_cast<Id>(ranges.size()), deflate);
      for (const auto& r : ranges) {
        if (box) {
          const auto c = boxed(r);
          w.write_partition(*c);
          finished(r, *c);
        } else {
          const ChunkStream c(m, r, sets, progress_of(r), cancel_requested);
          w.write_partition(c);
          finished(r, c);
        }
      }
      throw_if_cancelled(nothing_written);
      w.finish();
    } else {
      std::unique_ptr<ChunkSource> c;
      if (box) c = boxed(ranges[0]);
      else c = std::make_unique<ChunkStream>(m, ranges[0], sets, progress_of(ranges[0]), cancel_requested);
      // Committed after the last check for a signal: once the file is in
      // place, a signal no longer turns the export into "nothing written".
      PendingFile file;
      if (format == "exodus") write_exodus(*c, out, nullptr, &file);
      else write_msh(*c, out, format == "msh", &file);
      finished(ranges[0], *c);
      file->commit();
    }
  } catch (const Error&) {
    // The library stops a pass with an error of its own when the cancel
    // callback says so; the user's signal is the reason to report.
    throw_if_cancelled(nothing_written);
    throw;
  }
  if (box && written_elements == 0)  // a valid file, but rarely what was meant: said even under --quiet
    std::fprintf(stderr, "dicer export: note: the box holds no fine element; %s holds none\n", out.c_str());
  if (!quiet) {
    const Id n = static_cast<Id>(ranges.size());
    std::printf("exported %s: %lld fine elements, %lld nodes%s in %lld %s to %s\n", printable(path).c_str(),
                static_cast<long long>(written_elements), static_cast<long long>(written_nodes),
                n > 1 ? " (shared ones once per chunk)" : "", static_cast<long long>(n), n == 1 ? "chunk" : "chunks",
                printable(nemesis ? nemesis_path(out, n, 0) + (n > 1 ? " ... " + nemesis_path(out, n, n - 1) : "") : out)
                    .c_str());
  }
  store.report(m);
  return 0;
}

}  // namespace dicer::cli
