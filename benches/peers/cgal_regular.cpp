// CGAL's sequential 3D regular triangulation, the peer of `tetra-bench`
// (benches/src/bin/tetra_bench.rs), which compiles this file itself:
//
//   g++ -O3 -DNDEBUG -std=c++17 -frounding-math benches/peers/cgal_regular.cpp \
//       -o target/tetra-bench/cgal_regular -lgmp -lmpfr
//
// Usage: cgal_regular SPHERES.bin TETS.bin RUNS
//
// SPHERES.bin holds N spheres as little-endian f64 quadruples x, y, z, w (w the weight, a
// squared radius). The program builds `CGAL::Regular_triangulation_3` with the
// `Exact_predicates_inexact_constructions_kernel` (exact predicates, CGAL's symbolic
// perturbation for ties) RUNS times, each time into a fresh triangulation, and times only
// `insert(first, last)` (the range-of-pairs overload: spatial sort, then insertion; each
// vertex carries its input index). After the last run it writes the finite cells to TETS.bin
// as little-endian u32 quadruples of input indices, each sorted ascending, in CGAL's cell
// order. On stdout, one `key value` pair per line:
//
//   time SECONDS          wall time of insert (one line per run)
//   cpu SECONDS           process CPU time of insert (std::clock; one line per run)
//   vertices V            number_of_vertices() after the last run
//   hidden H              N - V: hidden points (duplicated centres included)
//   finite_cells C
//   input_peak_bytes B    VmHWM after reading the input, before the first triangulation
//   peak_bytes B          VmHWM at the end (before writing the cells)
//
// The cell base is CGAL's default, which keeps the hidden points in the cells.

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Regular_triangulation_3.h>
#include <CGAL/Regular_triangulation_vertex_base_3.h>
#include <CGAL/Triangulation_data_structure_3.h>
#include <CGAL/Triangulation_vertex_base_with_info_3.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fstream>
#include <iostream>
#include <string>
#include <utility>
#include <vector>

typedef CGAL::Exact_predicates_inexact_constructions_kernel K;
typedef CGAL::Regular_triangulation_vertex_base_3<K> Vb0;
typedef CGAL::Triangulation_vertex_base_with_info_3<std::size_t, K, Vb0> Vb;
typedef CGAL::Regular_triangulation_cell_base_3<K> Cb;
typedef CGAL::Triangulation_data_structure_3<Vb, Cb> Tds;
typedef CGAL::Regular_triangulation_3<K, Tds> Rt;
typedef Rt::Weighted_point Weighted_point;
typedef K::Point_3 Point;

// VmHWM of this process in bytes, or 0 when /proc is unavailable.
static long long peak_bytes() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmHWM:", 0) == 0) {
      return std::atoll(line.c_str() + 6) * 1024;
    }
  }
  return 0;
}

int main(int argc, char** argv) {
  if (argc != 4) {
    std::cerr << "usage: cgal_regular SPHERES.bin TETS.bin RUNS\n";
    return 2;
  }
  const int runs = std::atoi(argv[3]);
  if (runs < 1) {
    std::cerr << "RUNS must be at least 1\n";
    return 2;
  }

  std::vector<std::pair<Weighted_point, std::size_t>> input;
  {
    std::FILE* f = std::fopen(argv[1], "rb");
    if (!f) {
      std::cerr << "cannot open " << argv[1] << "\n";
      return 1;
    }
    std::fseek(f, 0, SEEK_END);
    const long bytes = std::ftell(f);
    std::fseek(f, 0, SEEK_SET);
    if (bytes < 0 || bytes % 32 != 0) {
      std::cerr << argv[1] << ": size is not a multiple of 32 bytes\n";
      return 1;
    }
    const std::size_t n = static_cast<std::size_t>(bytes) / 32;
    input.reserve(n);
    unsigned char buf[32];
    for (std::size_t i = 0; i < n; ++i) {
      if (std::fread(buf, 1, 32, f) != 32) {
        std::cerr << argv[1] << ": short read\n";
        return 1;
      }
      // Little-endian f64 on a little-endian host (x86-64, aarch64).
      double v[4];
      std::memcpy(v, buf, 32);
      input.emplace_back(Weighted_point(Point(v[0], v[1], v[2]), v[3]), i);
    }
    std::fclose(f);
  }
  const long long input_peak = peak_bytes();

  Rt* rt = nullptr;
  for (int run = 0; run < runs; ++run) {
    delete rt;
    rt = new Rt();
    const std::clock_t c0 = std::clock();
    const auto t0 = std::chrono::steady_clock::now();
    rt->insert(input.begin(), input.end());
    const auto t1 = std::chrono::steady_clock::now();
    const std::clock_t c1 = std::clock();
    std::printf("time %.6f\n", std::chrono::duration<double>(t1 - t0).count());
    std::printf("cpu %.6f\n", static_cast<double>(c1 - c0) / CLOCKS_PER_SEC);
    std::fflush(stdout);
  }
  const long long peak = peak_bytes();

  std::vector<std::array<std::uint32_t, 4>> cells;
  cells.reserve(rt->number_of_finite_cells());
  for (auto c = rt->finite_cells_begin(); c != rt->finite_cells_end(); ++c) {
    std::array<std::uint32_t, 4> t;
    for (int i = 0; i < 4; ++i) {
      t[i] = static_cast<std::uint32_t>(c->vertex(i)->info());
    }
    std::sort(t.begin(), t.end());
    cells.push_back(t);
  }
  {
    std::FILE* f = std::fopen(argv[2], "wb");
    if (!f || std::fwrite(cells.data(), sizeof(cells[0]), cells.size(), f) != cells.size()) {
      std::cerr << "cannot write " << argv[2] << "\n";
      return 1;
    }
    std::fclose(f);
  }
  std::printf("vertices %zu\n", static_cast<std::size_t>(rt->number_of_vertices()));
  std::printf("hidden %zu\n", input.size() - static_cast<std::size_t>(rt->number_of_vertices()));
  std::printf("finite_cells %zu\n", cells.size());
  std::printf("input_peak_bytes %lld\n", input_peak);
  std::printf("peak_bytes %lld\n", peak);
  delete rt;
  return 0;
}
