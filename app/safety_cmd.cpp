// `safestate safety check FILE | --default` and `safestate safety canonical FILE`.
#include <cstdio>
#include <fstream>
#include <iterator>
#include <optional>
#include <vector>
#include <string>

#include "safestate/safety/safety_config.hpp"
#include "safestate/safety/stopping_check.hpp"

namespace safestate::app {

namespace {
int report(const safety::Result& r, const std::string& what) {
  if (r.ok()) {
    std::printf("%s: valid\n%s", what.c_str(), safety::summary(*r.config).c_str());
    // @req STOP-CHECK
    for (const std::string& w : safety::stopping_warnings(*r.config)) std::printf("  warning: %s\n", w.c_str());
    return 0;
  }
  std::printf("%s: %zu error%s\n", what.c_str(), r.errors.size(), r.errors.size() == 1U ? "" : "s");
  for (const safety::Error& e : r.errors) std::printf("  %s\n", e.text().c_str());
  return 2;
}
}  // namespace

// Exit 0: valid (summary printed); 2: any error (every one printed).
int safety_check_main(const std::string& file, bool builtin) {
  if (builtin == !file.empty()) {
    std::fprintf(stderr, "safestate safety check: give a FILE or --default (one of them)\n");
    return 2;
  }
  if (builtin) return report(safety::parse_safety(safety::default_safety_text()), "built-in default");
  return report(safety::load_safety_file(file), file);
}

// The RFC 8785 form of any JSON file (not only a safety configuration) and its checksum:
// to compare with another implementation, or to see what the checksum covers.
int safety_canonical_main(const std::string& file, bool with_checksum) {
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    std::fprintf(stderr, "safestate safety canonical: cannot read %s\n", file.c_str());
    return 2;
  }
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<safety::Error> errors;
  const std::optional<std::string> c = safety::canonical_json(text, errors);
  if (!c) {
    for (const safety::Error& e : errors) std::fprintf(stderr, "%s: %s\n", file.c_str(), e.text().c_str());
    return 2;
  }
  std::fwrite(c->data(), 1, c->size(), stdout);
  std::printf("\n");
  if (with_checksum) std::printf("checksum %s (sha256 %s)\n", safety::checksum_text(*c).c_str(),
                                 safety::sha256_hex(*c).c_str());
  return 0;
}

}  // namespace safestate::app
