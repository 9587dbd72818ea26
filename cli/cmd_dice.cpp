// dicer dice: read a coarse mesh, resolve intervals, write the store.
#include <cstdio>

#include "common.hpp"
#include "dicer/coarse_mesh.hpp"
#include "dicer/error.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/store.hpp"

namespace dicer::cli {

static const char* kHelp = R"(Usage: dicer dice MESH -o STORE [interval options] [--quiet]

Refines every coarse element of MESH by transfinite interpolation, one
interval count per dicer sheet (see `dicer sheets`), and writes the fine
mesh implicitly to STORE (HDF5): coarse mesh, topology, sheets, intervals.
Nothing of the fine mesh itself is stored; `info`, `query` and `verify`
regenerate it on demand.

Interval options (precedence: sheet > block > size > global > 1):
  --interval N            every sheet gets N (default 1)
  --size H                each sheet gets the smallest N that makes all its
                          edges no longer than H
  --block-interval B=N    sheets touching block B (id or name) get N; a sheet
                          touching several such blocks gets the LARGEST, and
                          the conflict is reported (repeatable)
  --sheet-interval S=N    sheet S gets N, whatever its blocks ask (repeatable)
  --intervals-file FILE   JSON with any of these keys:
                          {"global": 4, "size": 0.05, "blocks": {"2": 6,
                          "inlet": 3}, "sheets": {"17": 12}}
                          flags on the command line override the file
Other options:
  -o, --output STORE      the store to write (written to a temporary name in
                          the same folder, renamed when complete)
  --quiet                 no summary on stdout

Example:
  dicer dice part.exo --interval 8 --block-interval 2=4 -o part.dice.h5
)";

int cmd_dice(const std::vector<std::string>& argv) {
  for (const auto& a : argv)
    if (a == "--help" || a == "-h") return std::fputs(kHelp, stdout), 0;
  std::vector<std::string> vflags = kIntervalFlags;
  vflags.push_back("-o");
  vflags.push_back("--output");
  Args args("dice", argv, vflags, {"--quiet"}, 1);
  const std::string in = args.need_positional(0, "MESH");
  auto out = args.value("-o");
  if (!out) out = args.value("--output");
  if (!out) throw Error(ErrorKind::Usage, "missing -o STORE (the output file)");
  const IntervalRequest req = interval_request(args);
  CoarseMesh mesh = read_coarse_mesh(in);
  for (const auto& w : mesh.warnings) std::fprintf(stderr, "dicer dice: warning: %s: %s\n", in.c_str(), w.c_str());
  std::vector<std::string> notes;
  const FineMesh fine = FineMesh::dice(std::move(mesh), req, &notes);
  for (const auto& n : notes) std::fprintf(stderr, "dicer dice: note: %s\n", n.c_str());
  {
    Progress bar("dice: writing", 1, args.has("--quiet"));
    write_store(fine, *out, [&](std::int64_t done, std::int64_t total) { bar.update(done, total); });
  }
  if (!args.has("--quiet"))
    std::printf("diced %s: %lld coarse %s -> %s fine nodes, %s fine elements (%lld sheets); wrote %s\n", in.c_str(),
                static_cast<long long>(fine.num_coarse_elements()), fine.mode() == Mode::Volume ? "hexes" : "quads",
                human_count(fine.num_nodes()).c_str(), human_count(fine.num_elements()).c_str(),
                static_cast<long long>(fine.info().sheets), out->c_str());
  return 0;
}

}  // namespace dicer::cli
