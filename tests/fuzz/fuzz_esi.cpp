// libFuzzer target: the ESI reader (ETG.2000 XML, input from outside) on arbitrary bytes. It
// must never crash; a refusal must name the file and leave the library as it was; a device
// refused on its own names the file; the others must have PDO entries whose sizes match their data types, and a
// bus configuration made from them (every device once, in file order) must be one the
// backend's own reader accepts, or a refusal with a reason.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "safestate/hal/esi.hpp"
#include "safestate/hal/ethercat.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace safestate::hal;
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::vector<esi::Device> lib(1);  // one device already there: a refusal must not touch it
  std::vector<std::string> warnings;
  std::string err;
  if (!esi::parse_esi(text, "fuzz.xml", lib, err, warnings)) {
    if (lib.size() != 1U || err.rfind("fuzz.xml", 0) != 0) __builtin_trap();
    return 0;
  }
  if (lib.size() < 2U || !err.empty()) __builtin_trap();
  std::vector<const esi::Device*> bus;
  for (std::size_t i = 1; i < lib.size() && bus.size() < 16U; ++i) {
    const esi::Device& d = lib[i];
    if (!d.error.empty()) {
      if (d.error.rfind("fuzz.xml:", 0) != 0) __builtin_trap();
      continue;  // refused when used: not on this bus
    }
    for (const auto* pdos : {&d.rx, &d.tx}) {
      for (const esi::Pdo& p : *pdos) {
        for (const esi::Entry& e : p.entries) {
          if (e.bits == 0U || (e.index != 0U && e.data_type == 0U)) __builtin_trap();
        }
      }
    }
    if (d.startup.size() > ethercat::kMaxStartupSdos) __builtin_trap();
    for (const ethercat::StartupSdo& s : d.startup) {
      if (s.index < 0x1000U || (s.size != 1U && s.size != 2U && s.size != 4U)) __builtin_trap();
    }
    (void)esi::image(d);
    bus.push_back(&d);
  }
  esi::GenOptions opt;
  opt.counts_per_revolution = 1048576;
  opt.source = "fuzz.xml";
  std::string json;
  std::string why;
  if (esi::make_bus_config(bus, opt, json, why, warnings)) {
    ethercat::BusConfig c;
    std::string again;
    if (!why.empty() || !ethercat::parse_bus_config(json, c, again)) __builtin_trap();
  } else if (why.empty() || !json.empty()) {
    __builtin_trap();
  }
  return 0;
}
