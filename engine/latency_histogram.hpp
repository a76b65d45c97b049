// Wake-up latency histogram of the servo loop: fixed log-spaced bins, no allocation, written by
// the servo thread only; readers take a Seqlock'd copy (engine/machine.hpp).
#pragma once

#include <array>
#include <cstdint>

namespace feedloop {

struct LatencyHistogram {
  // Bin i counts latencies in [edge(i), edge(i+1)) ns; edges 0, 1 us, then x1.25 per bin.
  static constexpr int kBins = 48;
  std::array<uint64_t, kBins> counts{};
  uint64_t samples = 0;
  int64_t max_ns = 0;

  static constexpr std::array<int64_t, kBins> kEdges = [] {
    std::array<int64_t, kBins> e{};
    double v = 1000.0;
    for (int i = 1; i < kBins; ++i, v *= 1.25) e[static_cast<size_t>(i)] = static_cast<int64_t>(v);
    return e;
  }();
  static int64_t edge_ns(int i) { return i <= 0 ? 0 : kEdges[static_cast<size_t>(i)]; }
  void add(int64_t latency_ns) {
    if (latency_ns < 0) latency_ns = 0;
    int i = 0;
    while (i + 1 < kBins && latency_ns >= edge_ns(i + 1)) ++i;
    ++counts[static_cast<size_t>(i)];
    ++samples;
    if (latency_ns > max_ns) max_ns = latency_ns;
  }
  // Upper edge of the bin holding quantile q (0..1): a conservative percentile.
  int64_t percentile_ns(double q) const {
    if (samples == 0) return 0;
    const auto target = static_cast<uint64_t>(q * static_cast<double>(samples));
    uint64_t acc = 0;
    for (int i = 0; i < kBins; ++i) {
      acc += counts[static_cast<size_t>(i)];
      if (acc > target) return i + 1 < kBins ? edge_ns(i + 1) : max_ns;
    }
    return max_ns;
  }
};

}  // namespace feedloop
