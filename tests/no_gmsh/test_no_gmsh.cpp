// A store diced against CAD is read and queried by a process that never
// links, loads or initialises Gmsh: this binary links dicer_store and
// dicer_core only. The CAD is made by Debian's python3-gmsh and diced by the
// CLI, in child processes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>

#include "dicer/store.hpp"
#include "dicer/sweep.hpp"
#include "dicer/verify.hpp"
#include "test_support.hpp"

namespace dicer {
namespace {

bool gmsh_mapped() {
  std::ifstream maps("/proc/self/maps");
  std::string line;
  while (std::getline(maps, line))
    if (line.find("libgmsh") != std::string::npos) return true;
  return false;
}

TEST(NoGmsh, StoreDicedAgainstCadIsQueriedWithoutGmsh) {
  test::TempDir tmp;
  const std::string cad = tmp.path("cyl.brep"), msh = tmp.path("cyl.msh"), store = tmp.path("cyl.dice.h5");
  const auto py = test::run_process(
      {"/usr/bin/python3", "-c",
       "import sys, gmsh\n"
       "gmsh.initialize(); gmsh.option.setNumber('General.Terminal', 0)\n"
       "gmsh.model.occ.addCylinder(0, 0, 0, 0, 0, 2, 1); gmsh.model.occ.synchronize()\n"
       "gmsh.write(sys.argv[1]); gmsh.finalize()\n",
       cad},
      {}, test::kForeignPythonEnv);
  if (py.exit_code != 0) DICER_SKIP_OR_FAIL_IN_CI("python3-gmsh cannot make the CAD: " + py.err);
  ASSERT_EQ(test::run_cli({"mesh-coarse", cad, "--size", "0.8", "-o", msh, "--quiet"}).exit_code, 0);
  const auto d = test::run_cli({"dice", msh, "--geometry", cad, "--interval", "5", "-o", store, "--quiet"});
  ASSERT_EQ(d.exit_code, 0) << d.err;

  const FineMesh s = read_store(store, StoreOptions{4ull << 20, 0});
  ASSERT_GT(s.num_bounding_nodes(), 0);
  // Every fine node on the boundary is on the analytic cylinder.
  double worst = 0;
  Id on = 0;
  NodeCursor cur(s);
  Id id;
  Vec3 p;
  while (cur.next(id, p)) {
    const double r = std::hypot(p.x, p.y);
    const double dd = std::min({std::abs(r - 1), std::abs(p.z), std::abs(p.z - 2)});
    if (dd < 1e-6) worst = std::max(worst, dd), ++on;
  }
  EXPECT_GT(on, s.num_bounding_nodes());
  EXPECT_LE(worst, 1e-12 * std::sqrt(12.0));
  EXPECT_TRUE(verify(s).ok());
  // The same checksum as the CLI's sweep (another process, other budget).
  const SweepResult mine = sweep(s, 2);
  const auto sw = test::run_cli({"sweep", store, "--json", "--threads", "1", "--cache-mb", "16", "--quiet"});
  ASSERT_EQ(sw.exit_code, 0) << sw.err;
  char hex[32];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(mine.checksum));
  EXPECT_NE(sw.out.find("\"checksum\":\"" + std::string(hex) + "\""), std::string::npos) << sw.out << " vs " << hex;
  // h5py (through HDF5's own shuffle filter and hdf5plugin's LZ4) reads the
  // bounding arrays as our cache does.
  std::uint64_t sum = 0;
  MeshCursor mc;
  for (Id r = 0; r < s.tables().bounding.rows(); ++r) {
    const std::int64_t* row = s.tables().bounding.row(r, mc.bounding);
    for (int k = 0; k < 3; ++k) sum += static_cast<std::uint64_t>(row[k]) * static_cast<std::uint64_t>(3 * r + k + 1);
  }
  const auto h5 = test::run_process(
      {"/usr/bin/python3", "-c",
       "import sys, h5py, hdf5plugin, numpy as np\n"
       "a = h5py.File(sys.argv[1], 'r')['geometry/bounding'][...].astype(np.uint64).ravel()\n"
       "w = np.arange(1, a.size + 1, dtype=np.uint64)\n"
       "print(int(np.sum(a * w, dtype=np.uint64)), a.size)\n",
       store},
      {}, test::kForeignPythonEnv);
  if (h5.exit_code != 0) DICER_SKIP_OR_FAIL_IN_CI("h5py cannot read the store: " + h5.err);
  EXPECT_EQ(h5.out, std::to_string(sum) + " " + std::to_string(3 * s.tables().bounding.rows()) + "\n");
  EXPECT_FALSE(gmsh_mapped());
}

}  // namespace
}  // namespace dicer
