// `safestate replay FILE... [--trace]`: read, parse and run each file; the exit code is
// the worst over all files (2 malformed or unreadable > 1 failed > 0).
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <iostream>
#include <string>
#include <utility>
#include <vector>

#include "safestate/scenario/scenario.hpp"
#include "trace.hpp"

namespace safestate::scenario {

namespace {

// A string with room for `n` characters that is on the heap even when short: one
// allocation whatever the length (a short string would otherwise fit in the string
// itself), so that two replays of different files allocate the same number of times.
std::string heap_string(std::size_t n) {
  std::string s;
  s.reserve(std::max<std::size_t>(n, 64U));
  return s;
}

// Reads the whole file into `text` with one allocation of its size.
// False: `why` says why.
bool read_file(const std::string& path, std::string& text, std::string& why) {
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) {
    why = "is a directory";
    return false;
  }
  errno = 0;
  std::ifstream f(path, std::ios::binary);
  if (!f) {
    why = (errno != 0) ? std::strerror(errno) : "cannot open";
    return false;
  }
  f.seekg(0, std::ios::end);
  const std::streamoff size = f.tellg();
  f.seekg(0, std::ios::beg);
  if (!f || size < 0) {
    why = "cannot determine its size";
    return false;
  }
  text = heap_string(static_cast<std::size_t>(size));
  text.resize(static_cast<std::size_t>(size));
  if (size > 0 && !f.read(text.data(), static_cast<std::streamsize>(size))) {
    why = "read error";
    return false;
  }
  return true;
}

void print_summary(std::ostream& report, const std::string& path, int rc, const Summary& s) {
  if (rc == 0) {
    report << "PASS " << path << " (" << s.expects << " expects, " << s.cycles << " cycles)\n";
  } else if (rc == 1) {
    report << "FAIL " << path << " (" << s.failed << " of " << s.expects << " expects failed, " << s.cycles
           << " cycles)\n";
  } else {
    report << "MALFORMED " << path << " (not run)\n";
  }
}

int replay_one(const std::string& path, bool trace, std::ostream& trace_out, std::ostream& report) {
  std::string text;
  std::string why;
  if (!read_file(path, text, why)) {
    report << path << ": cannot read: " << why << '\n';
    report << "ERROR " << path << " (not run)\n";
    return 2;
  }
  std::string name = heap_string(path.size());
  name = path;
  const ParseResult parsed = parse(text, std::move(name));
  if (!parsed.ok()) {
    report << parsed.error->text() << '\n';
    report << "MALFORMED " << path << " (not run)\n";
    return 2;
  }
  Summary summary;
  const RunOptions opts{trace, &trace_out, &report, nullptr, {}};
  const int rc = run(parsed.scenario, opts, summary);
  print_summary(report, path, rc, summary);
  return rc;
}

}  // namespace

// @req SCN-REPLAY
int replay(const std::vector<std::string>& files, bool trace, std::ostream& trace_out, std::ostream& report) {
  if (files.empty()) {
    report << "safestate replay: no scenario file given\n";
    return 2;
  }
  int worst = 0;
  for (const std::string& path : files) {
    if (trace && files.size() > 1) {
      trace_out << file_line(path) << '\n';
    }
    const int rc = replay_one(path, trace, trace_out, report);
    worst = (rc > worst) ? rc : worst;
  }
  trace_out.flush();
  report.flush();
  return worst;
}

int replay_main(const std::vector<std::string>& files, bool trace) {
  return replay(files, trace, std::cout, trace ? std::cerr : std::cout);
}

}  // namespace safestate::scenario
