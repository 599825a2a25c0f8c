// A standalone driver for the fuzz targets when built without libFuzzer (the default
// gcc build): runs every file of the given corpus folders, then N inputs from a fixed-
// seed generator. `make test` uses it as the smoke run; `make fuzz` uses libFuzzer.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);

int main(int argc, char** argv) {
  std::size_t files = 0;
  for (int i = 1; i < argc; ++i) {
    const std::filesystem::path p(argv[i]);
    std::vector<std::filesystem::path> inputs;
    if (std::filesystem::is_directory(p)) {
      for (const auto& e : std::filesystem::directory_iterator(p)) inputs.push_back(e.path());
    } else {
      inputs.push_back(p);
    }
    for (const auto& f : inputs) {
      std::ifstream in(f, std::ios::binary);
      const std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      LLVMFuzzerTestOneInput(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
      ++files;
    }
  }
  const char* env = std::getenv("FUZZ_SMOKE_RUNS");
  const long runs = (env != nullptr) ? std::atol(env) : 300;
  std::mt19937 rng(20261122U);
  for (long r = 0; r < runs; ++r) {
    std::vector<std::uint8_t> data(rng() % 512U);
    for (auto& b : data) b = static_cast<std::uint8_t>(rng());
    LLVMFuzzerTestOneInput(data.data(), data.size());
  }
  std::printf("%zu corpus inputs and %ld generated inputs ran without a finding\n", files, runs);
  return 0;
}
