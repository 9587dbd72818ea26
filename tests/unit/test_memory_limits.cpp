// What a memory cgroup leaves a process (detail::cgroup_memory_left): the
// limit of the process's group or of any ancestor, less what the group
// uses, in cgroup v2 and v1 layouts built in a temporary directory (the
// files' formats: the kernel's Documentation/admin-guide/cgroup-v2.rst and
// cgroup-v1/memory.rst). Without it a container's limit went unseen and an
// element that could not fit was allocated until the kernel killed us.
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>

#include "dicer/fine_mesh.hpp"
#include "test_support.hpp"

using dicer::detail::cgroup_memory_left;
namespace test = dicer::test;
namespace fs = std::filesystem;

namespace {
void put(const std::string& path, const std::string& text) {
  fs::create_directories(fs::path(path).parent_path());
  test::write_file(path, text);
}
}  // namespace

TEST(MemoryLimits, CgroupV2GroupAndAncestors) {
  test::TempDir d;
  const std::string root = d.path("cg");
  put(root + "/user.slice/job/memory.max", "max\n");
  put(root + "/user.slice/job/memory.current", "1000\n");
  put(root + "/user.slice/memory.max", "5000\n");
  put(root + "/user.slice/memory.current", "1500\n");
  // The ancestor's limit binds: 5000 - 1500.
  EXPECT_EQ(cgroup_memory_left("0::/user.slice/job\n", root), 3500u);
  // The group's own, tighter one: 2000 - 1000.
  put(root + "/user.slice/job/memory.max", "2000\n");
  EXPECT_EQ(cgroup_memory_left("0::/user.slice/job\n", root), 1000u);
  // Past its limit (usage can exceed it briefly): nothing left.
  put(root + "/user.slice/job/memory.current", "2500\n");
  EXPECT_EQ(cgroup_memory_left("0::/user.slice/job\n", root), 0u);
  // The page cache counts in memory.current but is reclaimed before the
  // kernel kills: inactive file pages are not spent (2000 - (2500 - 1200)).
  put(root + "/user.slice/job/memory.stat", "anon 1000\nfile 1500\nactive_file 300\ninactive_file 1200\n");
  EXPECT_EQ(cgroup_memory_left("0::/user.slice/job\n", root), 700u);
  // A namespace shows the group as the mount itself ("0::/").
  put(root + "/memory.max", "8000\n");
  put(root + "/memory.current", "500\n");
  EXPECT_EQ(cgroup_memory_left("0::/\n", root), 7500u);
  // No limit anywhere, or no such group: none.
  EXPECT_EQ(cgroup_memory_left("0::/elsewhere\n", d.path("empty")), UINT64_MAX);
  EXPECT_EQ(cgroup_memory_left("", root), UINT64_MAX);
  EXPECT_EQ(cgroup_memory_left("0::relative\nnot a line\n::\n", root), UINT64_MAX);  // odd lines: no throw
}

TEST(MemoryLimits, CgroupV1MemoryController) {
  test::TempDir d;
  const std::string root = d.path("cg");
  // v1 writes "no limit" as 2^63 - 1 rounded down to a page.
  put(root + "/memory/docker/abc/memory.limit_in_bytes", "9223372036854771712\n");
  put(root + "/memory/docker/abc/memory.usage_in_bytes", "100\n");
  put(root + "/memory/docker/memory.limit_in_bytes", "4096\n");
  put(root + "/memory/docker/memory.usage_in_bytes", "1096\n");
  const std::string self = "12:pids:/docker/abc\n4:cpu,memory:/docker/abc\n1:name=systemd:/docker/abc\n0::/\n";
  EXPECT_EQ(cgroup_memory_left(self, root), 3000u);
  put(root + "/memory/docker/memory.stat", "cache 900\ninactive_file 800\ntotal_inactive_file 1000\n");
  EXPECT_EQ(cgroup_memory_left(self, root), 4000u);  // v1's hierarchical total_ key, not the group's own
  // The memory controller alone decides: other controllers' limits are no
  // memory limits.
  EXPECT_EQ(cgroup_memory_left("4:cpu:/docker/abc\n", root), UINT64_MAX);
  EXPECT_EQ(cgroup_memory_left("4:memory:/other\n", root), UINT64_MAX);
}
