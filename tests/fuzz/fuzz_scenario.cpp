// libFuzzer target: the .scn parser on arbitrary text. It must never crash; a file it
// accepts must be runnable (short ones are run on the simulated cell) and its error
// messages must name a line.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <sstream>
#include <string>

#include "safestate/scenario/scenario.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const safestate::scenario::ParseResult r = safestate::scenario::parse(text, "fuzz.scn");
  if (!r.ok()) {
    if (r.error->line == 0U && !text.empty() && r.error->message.find("config") == std::string::npos) {
      std::fprintf(stderr, "error without a line: %s\n", r.error->text().c_str());
      __builtin_trap();
    }
    return 0;
  }
  if (r.scenario.cycles <= 3000U) {
    std::ostringstream sink;
    safestate::scenario::Summary summary{};
    const int rc = safestate::scenario::run(r.scenario, safestate::scenario::RunOptions{false, nullptr, &sink, nullptr, {}}, summary);
    if (rc != 0 && rc != 1) __builtin_trap();
  }
  return 0;
}
