// `safestate demo FILE`: replays a scenario on the simulated cell and narrates it in
// words: what the operator did (the comment of each input/command line), what the
// supervisor decided and why (transitions with their first-out cause), alarms raised
// and cleared, and every command's answer.
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "safestate/core/describe.hpp"
#include "safestate/scenario/scenario.hpp"
#include "safestate/sim/cell.hpp"

namespace safestate::app {

namespace {

std::string comment_of(const std::string& line) {
  const std::size_t h = line.find('#');
  if (h == std::string::npos) return {};
  std::string c = line.substr(h + 1);
  const std::size_t b = c.find_first_not_of(' ');
  return (b == std::string::npos) ? std::string{} : c.substr(b);
}

std::string body_of(const std::string& line) {
  std::string s = line.substr(0, line.find('#'));
  const std::size_t b = s.find(' ');
  s = (b == std::string::npos) ? s : s.substr(b);
  const std::size_t f = s.find_first_not_of(' ');
  const std::size_t l = s.find_last_not_of(' ');
  return (f == std::string::npos) ? std::string{} : s.substr(f, l - f + 1);
}

void print_status(const core::SupervisorOut& o, core::Cycle t) {
  std::printf("%7.3f s  %-18s %-15s mode %-4s contactor %-6s drives %-8s brakes %s\n",
              static_cast<double>(t) / 1000.0, core::to_string(o.state),
              o.sub == core::Sub::NONE ? "" : core::to_string(o.sub), core::to_string(o.mode),
              o.contactor ? "closed" : "open", o.drives_enable ? "enabled" : "disabled",
              o.brakes_release ? "released" : "engaged");
}

}  // namespace

int demo_main(const std::string& file) {
  std::ifstream in(file);
  if (!in) {
    std::fprintf(stderr, "safestate demo: cannot read %s\n", file.c_str());
    return 2;
  }
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string text = ss.str();
  std::vector<std::string> lines;
  std::istringstream ls(text);
  for (std::string l; std::getline(ls, l);) {
    lines.push_back(l);
  }
  const scenario::ParseResult parsed = scenario::parse(text, file);
  if (!parsed.ok()) {
    std::fprintf(stderr, "%s\n", parsed.error->text().c_str());
    return 2;
  }
  const scenario::Scenario& scn = parsed.scenario;
  sim::Cell cell(scn.config);
  std::printf("SafeState demo: a simulated ABB IRB 120 cell, 1 ms scan cycle (%s)\n\n", file.c_str());
  char words[160];
  std::size_t next = 0;
  float top_auto = 0.0F;
  float top_t1 = 0.0F;
  int failures = 0;
  for (core::Cycle t = 0; t < scn.cycles; ++t) {
    for (; next < scn.steps.size() && scn.steps[next].t == t; ++next) {
      const scenario::Step& s = scn.steps[next];
      const std::string& line = lines[s.line - 1U];
      if (const auto* i = std::get_if<scenario::InputStep>(&s.what)) {
        scenario::apply(*i, cell.inputs());
      } else if (const auto* c = std::get_if<scenario::CommandStep>(&s.what)) {
        static_cast<void>(cell.submit(c->command));
      } else if (const auto* f = std::get_if<scenario::FaultStep>(&s.what)) {
        cell.inject(f->fault);
      } else {
        continue;  // expects are checked by `safestate replay`
      }
      const std::string why = comment_of(line);
      const bool keepalive = body_of(line).rfind("cmd jog ", 0) == 0 && why.empty();
      if (!keepalive) {
        std::printf("%7.3f s  >> %-28s %s\n", static_cast<double>(t) / 1000.0, body_of(line).c_str(), why.c_str());
      }
    }
    cell.step();
    const core::SupervisorOut& o = cell.out();
    float& top = (o.mode == core::Mode::T1) ? top_t1 : top_auto;
    top = (cell.view().max_point_speed_mm_s > top) ? cell.view().max_point_speed_mm_s : top;
    for (std::size_t i = 0; i < o.reply_count; ++i) {
      const core::Reply& r = o.replies[i];
      if (r.result != core::Result::OK || r.cmd != static_cast<std::uint8_t>(core::CommandId::jog)) {
        std::printf("%7.3f s     answer: %s\n", static_cast<double>(t) / 1000.0, core::to_string(r.result));
      }
    }
    for (std::size_t a = 0; a < core::kAlarmCount; ++a) {
      const auto id = static_cast<core::AlarmId>(a);
      if ((o.alarms_raised & core::bit(id)) != 0U) {
        std::printf("%7.3f s     alarm %u %s: %s\n", static_cast<double>(t) / 1000.0, core::alarm_info(id).number,
                    core::alarm_info(id).name,
                    core::describe(id, cell.alarms().detail(id), words, sizeof words));
      }
      if ((o.alarms_cleared & core::bit(id)) != 0U) {
        std::printf("%7.3f s     cleared %s\n", static_cast<double>(t) / 1000.0, core::alarm_info(id).name);
      }
    }
    if (o.transition_count > 0U || t == 0U) {
      print_status(o, t);
      if (o.cause.kind != core::CauseKind::none && o.transition_count > 0U &&
          (o.state == core::State::STOPPING || o.state == core::State::ESTOP_ACTIVE || o.stop == core::StopCat::CAT0 ||
           o.state == core::State::ERROR_LOCKOUT)) {
        std::printf("           because: %s\n", core::describe(o.cause, words, sizeof words));
      }
    }
  }
  scenario::Summary summary{};
  std::ostringstream quiet;
  const int rc = scenario::run(scn, scenario::RunOptions{false, nullptr, &quiet, nullptr, {}}, summary);
  failures = static_cast<int>(summary.failed);
  std::printf("\nFastest point of the arm: %.0f mm/s in AUTO, %.0f mm/s in T1 (limit 250).\n",
              static_cast<double>(top_auto), static_cast<double>(top_t1));
  std::printf("%zu checks of the story: %s.\n", static_cast<std::size_t>(summary.expects),
              rc == 0 ? "all held" : "SOME FAILED");
  if (rc != 0) {
    std::printf("%s", quiet.str().c_str());
  }
  std::printf("Replay it cycle by cycle: build/bin/safestate replay --trace %s\n", file.c_str());
  return (failures == 0 && rc == 0) ? 0 : 1;
}

}  // namespace safestate::app
