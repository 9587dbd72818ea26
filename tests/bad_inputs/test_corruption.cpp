// One flipped byte per trial in a real store's pages (tests/tools/
// corruption.hpp, the logic behind scripts/corruption.sh): every trial reads
// identical data or raises a Corrupt error; none returns different data.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <cmath>
#include <cstring>
#include <filesystem>

#include "corruption.hpp"
#include "lz4_filter.hpp"
#include "dicer/store.hpp"
#include "store_forge.hpp"
#include "test_support.hpp"

using namespace dicer;

TEST(Corruption, FortyFlippedBytesNeverReadBackAsDifferentData) {
  test::TempDir tmp;
  const std::string store = tmp.path("sphere.dice.h5");
  IntervalRequest r;
  r.global = 4;
  write_store(FineMesh::dice(read_coarse_mesh(test::data_path("cardinal_sphere.e")), r), store);
  corruption::Trials trials(store, tmp.path("damaged.dice.h5"), 20240601);
  ASSERT_GT(trials.chunks().size(), 10u) << "every dataset is paged";
  corruption::Counts c;
  for (int i = 0; i < 40; ++i) {
    const corruption::TrialResult t = trials.run_one();
    c.add(t);
    EXPECT_NE(t.outcome, corruption::Outcome::DifferentData)
        << "trial " << i << ": " << t.chunk.dataset << " page " << t.chunk.page << " byte " << t.byte << ": " << t.message;
    EXPECT_NE(t.outcome, corruption::Outcome::OtherError) << "trial " << i << ": " << t.message;
    if (t.outcome == corruption::Outcome::Corrupt) {
      EXPECT_TRUE(t.named_page) << "trial " << i << ": the error names " << t.chunk.dataset << " page " << t.chunk.page
                                << ": " << t.message;
    }
  }
  EXPECT_EQ(c.different, 0u);
  EXPECT_GT(c.corrupt, 0u) << "no trial hit a page the readers check";
}

// The control: the same page damaged with a valid checksum (decoded, one
// coordinate nudged, re-encoded) is what the checksum stops. The sweep must
// see it as different data, or the trials above prove nothing.
TEST(Corruption, ADamagedPageWithAValidChecksumIsSeenAsDifferentData) {
  test::TempDir tmp;
  const std::string store = tmp.path("sphere.dice.h5");
  IntervalRequest r;
  r.global = 2;
  write_store(FineMesh::dice(read_coarse_mesh(test::data_path("cardinal_sphere.e")), r), store);
  corruption::Trials trials(store, tmp.path("damaged.dice.h5"), 1);
  const std::string forged = tmp.path("forged.dice.h5");
  std::filesystem::copy_file(store, forged);
  {
    // Both checksums (Fletcher32 and the CRC-32 companion) recomputed: only
    // the sweep's comparison can tell.
    hid_t f = H5Fopen(forged.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(f, 0);
    test::forge_page(f, "topology/element_corners", 0, [](std::vector<std::uint8_t>& page) {
      double x = 0;
      std::memcpy(&x, page.data() + 5 * sizeof(double), sizeof x);  // element 0, corner 1, z
      x = std::nextafter(x, 1e300);
      std::memcpy(page.data() + 5 * sizeof(double), &x, sizeof x);
    }, true);
    H5Fclose(f);
  }
  const corruption::TrialResult t = trials.check(forged, corruption::Chunk{"topology/element_corners", 0, 0, 0});
  EXPECT_EQ(t.outcome, corruption::Outcome::DifferentData) << t.message;
  EXPECT_FALSE(t.message.empty());
}
