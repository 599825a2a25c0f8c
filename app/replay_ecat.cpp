// `safestate replay --fieldbus ethercat`: a scenario file run by the real controller on
// the EtherCAT backend, against `safestate ecat-sim`. The file's `in` and `fault` lines
// go, as written, to the emulator's control channel before the cycle that must read
// them; one exchange per cycle keeps the emulator in lock-step with the file's cycles.
// One file per process (one master per process).
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "safestate/hal/ethercat.hpp"
#include "safestate/scenario/scenario.hpp"

namespace safestate::app {

namespace {

// The directive of line `n` as written: "@T in estop.a=0  # why" -> "in estop.a=0".
std::string directive(const std::vector<std::string>& lines, std::size_t n) {
  std::string s = (n >= 1U && n <= lines.size()) ? lines[n - 1U] : "";
  s = s.substr(0, s.find('#'));
  const std::size_t at = s.find('@');
  const std::size_t sp = s.find_first_of(" \t", at);
  s = (at == std::string::npos || sp == std::string::npos) ? "" : s.substr(sp);
  const std::size_t b = s.find_first_not_of(" \t");
  const std::size_t e = s.find_last_not_of(" \t\r");
  return (b == std::string::npos) ? "" : s.substr(b, e - b + 1U);
}

class Control {
 public:
  explicit Control(const std::string& path) {
    fd_ = socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un sa{};
    sa.sun_family = AF_UNIX;
    std::snprintf(sa.sun_path, sizeof sa.sun_path, "%s", path.c_str());
    if (connect(fd_, reinterpret_cast<sockaddr*>(&sa), sizeof sa) != 0) {
      close(fd_);
      fd_ = -1;
    }
  }
  ~Control() {
    if (fd_ >= 0) {
      close(fd_);
    }
  }
  Control(const Control&) = delete;
  Control& operator=(const Control&) = delete;
  [[nodiscard]] bool ok() const { return fd_ >= 0; }
  std::string ask(const std::string& line) {
    const std::string l = line + "\n";
    if (fd_ < 0 || send(fd_, l.data(), l.size(), MSG_NOSIGNAL) < 0) {
      return "ERROR control channel closed";
    }
    std::string answer;
    char c = 0;
    while (recv(fd_, &c, 1, 0) == 1 && c != '\n') {
      answer += c;
    }
    return answer;
  }

 private:
  int fd_ = -1;
};

}  // namespace

int replay_ethercat_main(const std::string& file, bool trace, const std::string& ifname, const std::string& control,
                         const std::string& bus_config) {
  std::ifstream f(file);
  if (!f) {
    std::cout << file << ": cannot read\nERROR " << file << " (not run)\n";
    return 2;
  }
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string text = ss.str();
  const scenario::ParseResult parsed = scenario::parse(text, file);
  if (!parsed.ok()) {
    std::cout << parsed.error->text() << "\nMALFORMED " << file << " (not run)\n";
    return 2;
  }
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) {
    lines.push_back(l);
  }
  hal::ethercat::BusConfig bc;
  std::string err;
  if (!(bus_config.empty() ? hal::ethercat::parse_bus_config(hal::ethercat::default_bus_config(), bc, err)
                           : hal::ethercat::load_bus_config(bus_config, bc, err))) {
    std::cerr << "safestate replay: bus configuration: " << err << '\n';
    return 2;
  }
  Control ctl(control);
  if (!ctl.ok()) {
    std::cerr << "safestate replay: cannot reach ecat-sim's control socket " << control << '\n';
    return 2;
  }
  // A replay is not paced in real time: the emulated plant steps once per exchange (lock-step)
  // instead of on the drives' SYNC0 pulses, so the file's cycles are the plant's cycles.
  if (const std::string answer = ctl.ask("plant lockstep"); answer != "OK") {
    std::cerr << "safestate replay: ecat-sim refused 'plant lockstep': " << answer << '\n';
    return 2;
  }
  // Every exchange waits for its frame (up to the frame timeout): a replay is not paced in
  // real time, and a frame late on a busy host must not change the scenario's outcome. For
  // the same reason the subdevices' process-data watchdogs get their longest time (10000
  // cycles): a replay pausing between two exchanges (it talks to the emulator's control
  // socket in between) is not a dead master, and a 10-cycle watchdog expiring in such a pause
  // took the emulated subdevices out of OP (FIELDBUS_LOST, a scenario failing for nothing
  // it describes).
  bc.watchdog_cycles = hal::ethercat::kMaxWatchdogCycles;
  hal::ethercat::Backend bus(bc, ifname, parsed.scenario.config.cycle_us, 0);
  if (!bus.booted()) {
    std::cerr << "safestate replay: " << bus.boot_error() << '\n';
  }
  // SPEC §11: the emulated arm carries the tool the safety configuration declares (its
  // drives' torques are then the arm's the core's collision model expects).
  {
    const core::SafetyLimits& lim = scenario::safety_limits(parsed.scenario);
    std::ostringstream tool;
    tool << "tool " << lim.payload_kg << ' ' << lim.tcp_mm[0] << ' ' << lim.tcp_mm[1] << ' ' << lim.tcp_mm[2];
    const std::string answer = ctl.ask(tool.str());
    if (answer != "OK") {
      std::cerr << "safestate replay: ecat-sim refused '" << tool.str() << "': " << answer << '\n';
      return 2;
    }
  }
  // SPEC §11: the simulated person's scanner fields, as the scenario configures them (the
  // person itself walks in the emulator: its `person` lines go there as the `in` lines do).
  {
    const sim::PersonSensors& ps = parsed.scenario.person_sensors;
    std::ostringstream fields;
    fields << "config person_fields=" << ps.outer_mm << ',' << ps.inner_mm;
    const std::string answer = ctl.ask(fields.str());
    if (answer != "OK") {
      std::cerr << "safestate replay: ecat-sim refused '" << fields.str() << "': " << answer << '\n';
      return 2;
    }
  }
  scenario::RunOptions opts{trace, &std::cout, trace ? &std::cerr : &std::cout, &bus, {}};
  opts.world = [&](const scenario::Step& step) {
    const std::string line = directive(lines, step.line);
    const std::string answer = ctl.ask(line);
    if (answer != "OK") {
      *opts.report << file << ':' << step.line << ": ecat-sim refused '" << line << "': " << answer << '\n';
      return false;
    }
    return true;
  };
  scenario::Summary summary;
  const int rc = scenario::run(parsed.scenario, opts, summary);
  *opts.report << (rc == 0 ? "PASS " : "FAIL ") << file << " over EtherCAT (" << summary.failed << " of "
               << summary.expects << " expects failed, " << summary.cycles << " cycles)\n";
  return rc;
}

}  // namespace safestate::app
