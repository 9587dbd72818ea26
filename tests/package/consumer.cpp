// Dice a mesh through the installed library and print the fine counts.
#include <dicer/fine_mesh.hpp>
#include <dicer/store.hpp>

#include <cstdio>

int main(int argc, char** argv) {
  if (argc < 2) return 2;
  dicer::IntervalRequest r;
  r.global = 2;
  const auto mesh = dicer::FineMesh::dice(dicer::read_coarse_mesh(argv[1]), r);
  std::printf("%lld %lld\n", static_cast<long long>(mesh.num_nodes()), static_cast<long long>(mesh.num_elements()));
  return 0;
}
