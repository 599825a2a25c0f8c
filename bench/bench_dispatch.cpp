// Dispatch cost per event, for each row of the transition table (Google Benchmark).
//
// Samples: cycles of recorded histories (random inputs, commands and faults on the real
// simulated cell, plus the typical shift and the worst path) in which the row fired,
// together with a copy of the supervisor as it was before that cycle. One iteration
// copies the supervisor and steps that cycle (signals + state machine + validation +
// monitors). `copy_only` times the copy alone and `quiet_cycle` a cycle in which no row
// fires, so that bench/run.py can report each row's cost as row - copy and its extra
// cost over a quiet cycle.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <string>
#include <vector>

#include "safestate/core/transitions.hpp"
#include "workload.hpp"

using namespace safestate;
using bench::Sample;

namespace {

struct RowSample {
  core::Supervisor before;
  Sample x;
};

constexpr std::size_t kPerRow = 32;
std::array<std::vector<RowSample>, core::kTransitionCount> g_rows;
std::vector<RowSample> g_quiet;

void collect(const bench::Trace& life) {
  core::Supervisor s{core::to_timing(core::Config{})};
  s.configure_arm(bench::workload_arm(), bench::kWorkloadTcp);  // as the cell's (T1 speed)
  core::SupervisorOut out{};
  for (const Sample& x : life) {
    const core::Supervisor before = s;
    s.step(x.raw, x.fb, x.cmds.data(), x.n, out);
    if (out.transition_count == 0U && out.reply_count == 0U && g_quiet.size() < 4U * kPerRow) {
      g_quiet.push_back({before, x});
    }
    const auto add = [&](std::uint8_t r) {
      if (r < core::kTransitionCount && g_rows[r].size() < kPerRow) {
        g_rows[r].push_back({before, x});
      }
    };
    for (std::size_t i = 0; i < out.transition_count; ++i) {
      add(out.transitions[i].row);
    }
    // Rows that keep the state (reset in IDLE, the jog keep-alive, confirm_t2) report no
    // transition: their command's OK names them, through the same index the core uses.
    for (std::size_t i = 0; i < out.reply_count; ++i) {
      const core::Reply& rp = out.replies[i];
      if (rp.result == core::Result::OK && rp.cmd < core::kCommandCount) {
        const core::Leaf l = before.manager().leaf();
        const auto trig = core::trigger_of(static_cast<core::CommandId>(rp.cmd));
        const std::uint8_t r = core::kIndex[static_cast<std::size_t>(l)][static_cast<std::size_t>(trig)];
        if (r < core::kTransitionCount && core::kTransitions[r].to == core::Leaf::SAME) {
          add(r);
        }
      }
    }
  }
}

void step_samples(benchmark::State& state, const std::vector<RowSample>* v) {
  std::size_t i = 0;
  core::SupervisorOut out{};
  for (auto _ : state) {
    const RowSample& rs = (*v)[i];
    i = (i + 1U == v->size()) ? 0U : i + 1U;
    core::Supervisor s = rs.before;
    s.step(rs.x.raw, rs.x.fb, rs.x.cmds.data(), rs.x.n, out);
    benchmark::DoNotOptimize(out);
    benchmark::ClobberMemory();
  }
}

void copy_only(benchmark::State& state, const std::vector<RowSample>* v) {
  std::size_t i = 0;
  for (auto _ : state) {
    const RowSample& rs = (*v)[i];
    i = (i + 1U == v->size()) ? 0U : i + 1U;
    core::Supervisor s = rs.before;
    benchmark::DoNotOptimize(s);
    benchmark::ClobberMemory();
  }
}

}  // namespace

int main(int argc, char** argv) {
  for (const bench::Trace& life : bench::random(3000000, 7)) {
    collect(life);
  }
  collect(bench::shift(300000));
  collect(bench::manual_program());
  collect(bench::manual_jog());
  collect(bench::worst());
  benchmark::RegisterBenchmark("copy_only", copy_only, &g_quiet);
  benchmark::RegisterBenchmark("quiet_cycle", step_samples, &g_quiet);
  for (std::size_t r = 0; r < core::kTransitionCount; ++r) {
    const std::string name = std::string("row/") + core::kTransitions[r].id;
    if (g_rows[r].empty()) {
      std::fprintf(stderr, "bench_dispatch: %s was never reached by the recorded histories\n", name.c_str());
      continue;
    }
    benchmark::RegisterBenchmark(name.c_str(), step_samples, &g_rows[r]);
  }
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
