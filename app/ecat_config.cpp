// `safestate ecat-config --esi FILE... (--device SPEC... | --scan IF) [--counts-per-rev N|AXIS=N...] [--out FILE]`:
// ETG.2000 ESI files -> the bus configuration of `safestate run --fieldbus ethercat
// --bus-config FILE` (docs/ethercat.md "ESI"). Exit 0 written, 2 bad input (nothing written).
#include <CLI/CLI.hpp>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "safestate/hal/ecat_master.hpp"
#include "safestate/hal/esi.hpp"

namespace safestate::app {

struct EcatConfigOptions {
  std::vector<std::string> esi;
  std::vector<std::string> devices;
  std::string scan;
  std::vector<std::string> counts;  // "N" for every drive, "AXIS=N" for one
  std::uint32_t frame_timeout_us = 20000;
  std::string out;
};

namespace {

// The identities on the segment at `ifname`, in bus order (our master's scan: the
// subdevices are left in PRE-OP).
bool scan_segment(const std::string& ifname, std::uint32_t frame_timeout_us, std::vector<hal::esi::Identity>& out,
                  std::string& err) {
  char e[256] = {};
  SsEcatMaster* m = ss_ecat_open(ifname.c_str(), frame_timeout_us, 5000, 0, e, sizeof e);
  if (m == nullptr) {
    err = std::string("--scan ") + ifname + ": " + e;
    return false;
  }
  std::array<SsEcatSub, 16> found{};
  const int n = ss_ecat_scan(m, found.data(), found.size());
  if (n < 0) {
    err = std::string("--scan ") + ifname + ": " + ss_ecat_error(m);
    return false;
  }
  if (n == 0 || n > static_cast<int>(found.size())) {
    err = "--scan " + ifname + ": " + std::to_string(n) + " subdevices found (a bus configuration has 1..16)";
    return false;
  }
  for (int i = 0; i < n; ++i) {
    out.push_back({found[static_cast<std::size_t>(i)].vendor_id, found[static_cast<std::size_t>(i)].product_code,
                   found[static_cast<std::size_t>(i)].revision});
  }
  return true;
}

EcatConfigOptions g_ecat_config;

int refuse(const std::string& why) {
  std::fprintf(stderr, "safestate ecat-config: %s\n", why.c_str());
  return 2;
}

}  // namespace

int ecat_config_main(const EcatConfigOptions& opt) {
  if (opt.esi.empty()) {
    return refuse("give the ESI files with --esi FILE...");
  }
  if (opt.devices.empty() == opt.scan.empty()) {
    return refuse("give the bus order: --device SPEC... (in bus order) or --scan IF (one of them)");
  }
  std::vector<hal::esi::Device> library;
  std::vector<std::string> warnings;
  for (const std::string& f : opt.esi) {
    std::string err;
    if (!hal::esi::load_esi(f, library, err, warnings)) {
      return refuse(err);
    }
  }
  std::vector<const hal::esi::Device*> bus;
  std::string err;
  if (!hal::esi::check_library(library, err)) {
    return refuse(err);
  }
  std::string source;
  if (!opt.scan.empty()) {
    std::vector<hal::esi::Identity> found;
    if (!scan_segment(opt.scan, opt.frame_timeout_us, found, err) || !hal::esi::resolve_scanned(library, found, bus, err)) {
      return refuse(err);
    }
    source = "a scan of " + opt.scan;
  } else {
    if (!hal::esi::resolve_bus(library, opt.devices, bus, err)) {
      return refuse(err);
    }
    source = "--device";
    for (const std::string& d : opt.devices) {
      source += " " + d;
    }
  }
  std::string files;
  for (const std::string& f : opt.esi) {
    files += (files.empty() ? "" : ", ") + f;
  }
  hal::esi::GenOptions g;
  // --counts-per-rev N (every drive) and AXIS=N (that axis), each N 1..2^31.
  for (const std::string& c : opt.counts) {
    const auto eq = c.find('=');
    const std::string a = eq == std::string::npos ? "" : c.substr(0, eq);
    const std::string n = eq == std::string::npos ? c : c.substr(eq + 1U);
    const auto whole = [](const std::string& t, std::uint64_t lo, std::uint64_t hi, std::uint32_t& v) {
      if (t.empty() || t.size() > 10U || t.find_first_not_of("0123456789") != std::string::npos) {
        return false;
      }
      const std::uint64_t x = std::stoull(t);
      v = static_cast<std::uint32_t>(x);
      return x >= lo && x <= hi;
    };
    std::uint32_t axis = 0;
    std::uint32_t counts = 0;
    if ((eq != std::string::npos && !whole(a, 1, 16, axis)) || !whole(n, 1, 1ULL << 31U, counts)) {
      return refuse("--counts-per-rev " + c + ": expected N or AXIS=N (N increments per revolution, 1..2147483648)");
    }
    if (eq == std::string::npos) {
      if (g.counts_per_revolution != 0U) {
        return refuse("--counts-per-rev " + c + ": the resolution of every drive is given twice");
      }
      g.counts_per_revolution = counts;
    } else if (!g.counts_by_axis.emplace(axis, counts).second) {
      return refuse("--counts-per-rev " + c + ": axis " + std::to_string(axis) + " is given twice");
    }
  }
  g.frame_timeout_us = opt.frame_timeout_us;
  g.source = files + " (bus order: " + source + ")";
  std::string json;
  if (!hal::esi::make_bus_config(bus, g, json, err, warnings)) {
    return refuse(err);
  }
  for (const std::string& w : warnings) {
    std::fprintf(stderr, "safestate ecat-config: warning: %s\n", w.c_str());
  }
  if (opt.out.empty()) {
    std::fputs(json.c_str(), stdout);
    return 0;
  }
  // Written whole or not at all: a temporary file beside it, renamed over it.
  const std::string tmp = opt.out + ".tmp." + std::to_string(::getpid());
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    f << json;
    f.flush();
    if (!f) {
      std::remove(tmp.c_str());
      return refuse("cannot write " + opt.out);
    }
  }
  if (std::rename(tmp.c_str(), opt.out.c_str()) != 0) {
    std::remove(tmp.c_str());
    return refuse("cannot write " + opt.out);
  }
  std::fprintf(stderr, "safestate ecat-config: %zu subdevices written to %s\n", bus.size(), opt.out.c_str());
  return 0;
}

CLI::App* add_ecat_config_command(CLI::App& app) {
  auto* c = app.add_subcommand("ecat-config",
                               "ETG.2000 ESI files -> the EtherCAT bus configuration (exit 0 written, 2 bad input)");
  c->add_option("--esi", g_ecat_config.esi, "ESI files (XML) describing the devices")->expected(1, -1);
  c->add_option("--device", g_ecat_config.devices,
                "the bus in order: PRODUCT (0x...) or ESI TYPE, optionally /REVISION and *COUNT "
                "(e.g. --device 0x00D10018 --device 0x00402001*6)")
      ->expected(1, -1);
  c->add_option("--scan", g_ecat_config.scan, "take the bus order from a scan of the segment on this interface");
  c->add_option("--counts-per-rev", g_ecat_config.counts,
                "the drives' encoder increments per revolution, N for every drive or AXIS=N for one (an ESI does not "
                "carry it)")
      ->expected(1, -1);
  c->add_option("--frame-timeout-us", g_ecat_config.frame_timeout_us, "the start-up frames' timeout (default 20000)")
      ->check(CLI::Range(100, 100000));
  c->add_option("--out", g_ecat_config.out, "write the configuration here (default: standard output)");
  return c;
}

int run_ecat_config_command() { return ecat_config_main(g_ecat_config); }

}  // namespace safestate::app
