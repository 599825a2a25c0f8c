#include "safestate/pair/shm.hpp"

#include <cstdio>

#include "safestate/controller/platform.hpp"

namespace safestate::pair {

std::uint32_t setup_crc(const Setup& s) noexcept {
  return controller::crc32(0U, reinterpret_cast<const volatile unsigned char*>(&s), offsetof(Setup, crc));
}

bool setup_valid(const Setup& s, const char*& why) noexcept {
  if (s.magic != kMagic) {
    why = "not a SafeState channel setup (magic)";
    return false;
  }
  if (s.version != kVersion || s.size != sizeof(Setup)) {
    why = "the host is another build (version or size of the setup differ)";
    return false;
  }
  if (s.crc != setup_crc(s)) {
    why = "the setup's CRC does not match its bytes";
    return false;
  }
  return true;
}

void seal_setup(Setup& s, const motion::RobotModel& model) noexcept {
  s.magic = kMagic;
  s.version = kVersion;
  s.size = sizeof(Setup);
  s.model = model;
  s.model.name = nullptr;
  std::snprintf(s.model_name, sizeof s.model_name, "%s", model.name != nullptr ? model.name : "");
  for (std::size_t k = 0; k < motion::kLinks; ++k) {
    s.model.link_names[k] = nullptr;
    std::snprintf(s.link_names[k], sizeof s.link_names[k], "%s",
                  model.link_names[k] != nullptr ? model.link_names[k] : "");
  }
  s.crc = setup_crc(s);
}

bool LaneReader::next(controller::Digest& d) noexcept {
  if (lane_ == nullptr) {
    return false;
  }
  const std::uint64_t written = lane_->written.load(std::memory_order_acquire);
  if (read_ >= written) {
    return false;
  }
  if (written - read_ > kLaneSlots) {
    read_ = written - kLaneSlots;  // fell behind: the oldest still kept (a gap in seq)
  }
  const std::uint64_t n = read_ + 1U;
  for (int attempt = 0; attempt < 4; ++attempt) {
    if (lane_->slots[n % kLaneSlots].read(d)) {
      read_ = n;
      return true;
    }
  }
  return false;  // being written over and over: the next call tries again
}

void ShmLink::send(const controller::Digest& d) noexcept {
  const std::uint64_t n = mine_->written.load(std::memory_order_relaxed) + 1U;
  mine_->slots[n % kLaneSlots].write(d);
  mine_->written.store(n, std::memory_order_release);
}

bool make_names(const char* base, Names& out) noexcept {
  if (base == nullptr || base[0] != '/') {
    return false;
  }
  const int a = std::snprintf(out.in, sizeof out.in, "%s-in", base);
  const int b = std::snprintf(out.a, sizeof out.a, "%s-a", base);
  const int c = std::snprintf(out.b, sizeof out.b, "%s-b", base);
  return a > 0 && b > 0 && c > 0 && static_cast<std::size_t>(a) < sizeof out.in &&
         static_cast<std::size_t>(b) < sizeof out.a && static_cast<std::size_t>(c) < sizeof out.b;
}

}  // namespace safestate::pair
