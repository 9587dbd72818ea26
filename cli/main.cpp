// dicer: the command-line tool. One file per subcommand; this one dispatches
// and turns dicer::Error into a one-line message and an exit code (the one
// mapping is exit_code(), cli/exit_codes.cpp).
#include <sys/resource.h>

#include <cstdio>
#include <exception>
#include <new>
#include <string>
#include <vector>

#include "common.hpp"
#include "dicer/store.hpp"
#include "dicer/version.hpp"
#include "dicer/error.hpp"
#include "exit_codes.hpp"
#include "hdf5_file.hpp"

namespace {

struct CommandEntry {
  const char* name;
  const char* args;     // shown after the name in `dicer --help`
  const char* summary;  // lines after the first are indented under it
  int (*run)(const std::vector<std::string>&);
  bool distributed = false;  // has an MPI mode (rank r on chunk r; dice: the CAD work shared); else rank 0 runs it alone
};

// In the order you use them.
const CommandEntry kCommands[] = {
    {"mesh-coarse", "CAD -o MESH",
     "coarse all-hex (--surface: all-quad) mesh of a STEP\nor BREP model with Gmsh, for dice --geometry CAD",
     dicer::cli::cmd_mesh_coarse},
    {"sheets", "MESH", "list the dicer sheets (edges that must share one\ninterval)", dicer::cli::cmd_sheets},
    {"dice", "MESH -o STORE", "choose intervals and write the implicit fine mesh", dicer::cli::cmd_dice, true},
    {"info", "STORE", "counts, blocks and settings of a store", dicer::cli::cmd_info},
    {"query", "STORE", "fine nodes and elements by id, or in a box", dicer::cli::cmd_query, true},
    {"verify", "STORE",
     "stream through every fine element and check\nconformity, counts, coincident nodes and quality",
     dicer::cli::cmd_verify, true},
    {"footprint", "STORE", "bytes on disk and in memory vs an explicit mesh", dicer::cli::cmd_footprint},
    {"export", "STORE", "a chunk, a box or the whole mesh to VTKHDF, MSH 4.1\nor Exodus II", dicer::cli::cmd_export,
     true},
    {"sweep", "STORE", "every fine node and element in N threads, rate and\nchecksum", dicer::cli::cmd_sweep, true},
    {"transfer", "COARSE FINE",
     "whether two stores are nested, and the prolongation\nbetween them (CSR in HDF5, PETSc binary)",
     dicer::cli::cmd_transfer},
};

std::string usage() {
  std::string s = R"(dicer - refine coarse all-hex (or all-quad) meshes into huge conforming
fine meshes that are stored implicitly: coarse mesh + intervals + recipe.

Usage: dicer <command> [options]      dicer help <command> for details

Commands (in the order you use them):
)";
  for (const auto& c : kCommands) {
    std::string head = std::string("  ") + c.name + " " + c.args;
    head += head.size() < 27 ? std::string(27 - head.size(), ' ') : "\n" + std::string(27, ' ');
    std::string summary = c.summary;
    for (size_t p = summary.find('\n'); p != std::string::npos; p = summary.find('\n', p + 1))
      summary.insert(p + 1, std::string(27, ' '));
    s += head + summary + "\n";
  }
  s += R"(
mesh-coarse and --geometry run dicer-cad (the same commands built with Gmsh),
installed beside dicer; DICER_CAD=PATH overrides where it is found. A CAD
file's read ends as an error after 30 s + 60 s per MiB of the file, and
mesh-coarse's meshing after 300 s + 1 ms per expected element, of CPU time
(OpenCASCADE and Gmsh loop on some damaged files); DICER_CAD_READ_SECONDS=S
and DICER_CAD_MESH_SECONDS=S set them.

MESH is an Exodus II file (.e .exo .ex2 .g) or a Gmsh MSH 2.2/4.1 file
(ASCII or binary) holding hexahedra (volume dicing) or quadrilaterals
(surface dicing). STORE is the HDF5 file `dice` writes (.dice.h5). Every
file argument must be a regular file (not a directory or a FIFO), and an
output may not be the same file as an input; outputs appear whole under
their name (written to a temporary file, then renamed), so -o - is refused
rather than taken as standard output (./- names a file called -).

Options are written --name VALUE or --name=VALUE; when an option that
takes one value is given twice, the last one counts. Options marked
"repeatable" keep every value. `--` ends the options: an argument after
it is a file name even when it starts with '-' (dicer info -- -a.dice.h5).

JSON (--json): one line per document, UTF-8. Bytes of a string that are
not valid UTF-8 (a file or block name) become U+FFFD; a number that is not
finite (NaN, Inf) is written as null; doubles are written in the shortest
form that reads back to the same bits (at most 17 significant digits).

Examples:
  dicer sheets examples/cardinal_sphere.e
  dicer dice examples/cardinal_sphere.e --interval 8 -o sphere.dice.h5
  dicer mesh-coarse part.step --size 4 -o coarse.msh
  dicer dice coarse.msh --geometry part.step --interval 10 -o part.dice.h5
  dicer info sphere.dice.h5
  dicer query sphere.dice.h5 --element 1000 --json
  dicer verify sphere.dice.h5

)";
  return s + dicer::cli::exit_code_help();
}

}  // namespace

int main(int argc, char** argv) {
  using namespace dicer::cli;
  using dicer::ErrorKind;
  std::vector<std::string> args(argv + 1, argv + argc);
  // What is answered before MPI starts is printed by one rank under mpirun.
  const bool speaks = dicer::mpi::launched_rank() == 0;
  if (args.size() >= 2 && args[0] == "help" && args[1].rfind("-", 0) != 0) args = {args[1], "--help"};  // dicer help export
  if (args.empty() || args[0] == "--help" || args[0] == "-h" || args[0] == "help") {
    if (speaks) std::fputs(usage().c_str(), args.empty() ? stderr : stdout);
    return args.empty() ? exit_code(ErrorKind::Usage, 0) : kExitSuccess;
  }
  if (args[0] == "--version") {
    if (speaks) std::printf("dicer %s (store format %d)\n", dicer::kVersion, dicer::kStoreFormatVersion);
    return kExitSuccess;
  }
  const CommandEntry* command = nullptr;
  std::string names;
  for (const auto& c : kCommands) {
    if (args[0] == c.name) command = &c;
    names += (names.empty() ? "" : ", ") + std::string(c.name);
  }
  if (!command) {
    if (speaks)
      std::fprintf(stderr, "dicer: error: unknown command \"%s\" (commands: %s; see dicer --help)\n", printable(args[0]).c_str(),
                   names.c_str());
    return exit_code(ErrorKind::Usage, 0);
  }
  dicer::h5::no_cleanup_at_exit();  // before MPI starts; see there: an Exodus export on a full disk crashed at exit
  // Commands that need the CAD re-execute dicer-cad before MPI starts
  // (dicer-cad starts its own session).
  try {
    hand_over_if_cad(argv, args);
  } catch (const dicer::Error& e) {
    std::fprintf(stderr, "dicer %s: error: %s\n", command->name, printable(e.what()).c_str());
    return exit_code(e.kind(), received_signal());
  }
  // Under mpirun every rank runs the command; errors are agreed between
  // ranks (dicer::mpi::checkpoint) so all end with one code and only the
  // failing rank prints; an error that escaped agreement ends the job.
  dicer::mpi::Session mpi(argc, argv);
  set_session(&mpi);
  dicer::mpi::set_signal_probe(&received_signal);
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  int code = kExitSuccess;
  bool caught = false;
  try {
    // Every rank must run the same command line: ranks given others
    // (mpirun -np 2 dicer sweep S : -np 1 dicer verify S) waited for each
    // other for ever in different collectives.
    if (mpi.active()) {
      auto words = [](const std::string& nul_separated) {
        std::vector<std::string> w;
        for (size_t at = 0; at < nul_separated.size();) {
          const size_t end = nul_separated.find('\0', at);
          w.push_back(nul_separated.substr(at, end - at)), at = end + 1;
        }
        return w;
      };
      auto cut = [](const std::string& s) { return s.size() > 60 ? s.substr(0, 57) + "..." : s; };
      std::string mine;
      for (const auto& a : args) mine += a + '\0';
      dicer::mpi::require_same(mpi.comm(), mine, ErrorKind::Usage, [&](int q, const std::string& first) {
        // The first word that differs, so that long lines are told apart.
        const std::vector<std::string> a = words(mine), b = words(first);
        size_t k = 0;
        while (k < a.size() && k < b.size() && a[k] == b[k]) ++k;
        const std::string here = k < a.size() ? "\"" + cut(a[k]) + "\"" : "nothing";
        const std::string there = k < b.size() ? "\"" + cut(b[k]) + "\"" : "nothing";
        return "rank " + std::to_string(q) + " runs another command line than rank 0 (word " + std::to_string(k + 1) +
               " after dicer: " + here + " against " + there + "): every rank must run the same command line";
      });
    }
    bool help = false;
    for (const auto& a : options_part(rest)) help = help || a == "--help" || a == "-h";
    code = command->distributed && !help ? command->run(rest) : on_rank0([&] { return command->run(rest); });
  } catch (const dicer::mpi::PeerFailed& e) {
    const int k = static_cast<int>(e.kind());
    return k < 0 ? kExitInternal : exit_code(e.kind(), e.signal() ? e.signal() : received_signal());
  } catch (const dicer::Error& e) {
    std::fprintf(stderr, "dicer %s: error: %s\n", command->name, printable(e.what()).c_str());
    code = exit_code(e.kind(), received_signal()), caught = true;
  } catch (const std::bad_alloc&) {
    // Say which limit: a user's ulimit -v (batch systems set one) or the
    // machine. Nothing allocated here: memory may still be short.
    struct rlimit as {};
    char limit[96] = "the machine's free memory";
    if (::getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY) {
      const double mib = static_cast<double>(as.rlim_cur) / (1 << 20);
      std::snprintf(limit, sizeof limit, "this process's address-space limit, %.1f %s (ulimit -v)",
                    mib >= 1024 ? mib / 1024 : mib, mib >= 1024 ? "GiB" : "MiB");
    }
    std::fprintf(stderr, "dicer %s: error: out of memory: the command needs more than %s allows\n", command->name,
                 limit);
    code = kExitInternal, caught = true;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "dicer %s: internal error: %s\n", command->name, printable(e.what()).c_str());
    code = kExitInternal, caught = true;
  }
  if (caught && mpi.active() && !dicer::mpi::error_was_agreed()) {
    std::fflush(stderr);
    MPI_Abort(mpi.comm(), code);
  }
  return code;
}
