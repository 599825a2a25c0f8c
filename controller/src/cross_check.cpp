#include "safestate/controller/cross_check.hpp"

#include <cstddef>

#include "safestate/controller/cell.hpp"
#include "safestate/controller/platform.hpp"

namespace safestate::controller {

namespace {

static_assert(sizeof(Digest) == 40U, "the digest is its bytes: no hidden padding");
static_assert(offsetof(Digest, crc) == sizeof(Digest) - sizeof(std::uint32_t), "the CRC is last");

std::uint32_t digest_crc(const Digest& d) noexcept {
  return crc32(0U, reinterpret_cast<const unsigned char*>(&d), offsetof(Digest, crc));
}

std::uint32_t replies_crc(const core::SupervisorOut& out) noexcept {
  std::uint32_t c = 0;
  for (std::size_t i = 0; i < out.reply_count && i < out.replies.size(); ++i) {
    const core::Reply& r = out.replies[i];
    const std::array<unsigned char, 7> b{static_cast<unsigned char>(r.seq & 0xFFU),
                                         static_cast<unsigned char>((r.seq >> 8U) & 0xFFU),
                                         static_cast<unsigned char>((r.seq >> 16U) & 0xFFU),
                                         static_cast<unsigned char>((r.seq >> 24U) & 0xFFU),
                                         r.cmd,
                                         r.source,
                                         static_cast<unsigned char>(r.result)};
    c = crc32(c, b.data(), b.size());
  }
  return c;
}

}  // namespace

Digest make_digest(std::uint32_t seq, std::uint64_t cycle, const core::SupervisorOut& out) noexcept {
  Digest d{};
  d.seq = seq;
  d.cycle = cycle;
  d.alarms = out.alarms;
  d.state = static_cast<std::uint8_t>(out.state);
  d.sub = static_cast<std::uint8_t>(out.sub);
  d.stop = static_cast<std::uint8_t>(out.stop);
  d.outputs = output_bits(out);
  d.brake_test_axis = out.brake_test_axis;
  d.reply_count = out.reply_count;
  d.replies = replies_crc(out);
  d.crc = digest_crc(d);
  return d;
}

bool sealed(const Digest& d) noexcept { return digest_crc(d) == d.crc; }

DigestField first_difference(const Digest& a, const Digest& b) noexcept {
  if (a.cycle != b.cycle) return DigestField::cycle;
  if (a.state != b.state) return DigestField::state;
  if (a.sub != b.sub) return DigestField::sub;
  if (a.stop != b.stop) return DigestField::stop;
  if (a.alarms != b.alarms) return DigestField::alarms;
  if (a.outputs != b.outputs) return DigestField::outputs;
  if (a.brake_test_axis != b.brake_test_axis) return DigestField::brake_test_axis;
  if (a.reply_count != b.reply_count || a.replies != b.replies) return DigestField::replies;
  return DigestField::none;
}

void CrossCheck::take(const Digest& theirs) noexcept {
  // A wrong CRC, a repeated or a skipped sequence number: not arrived (and the sequence is
  // not resynchronised by it: only the next number counts).
  if (!sealed(theirs) || (have_seq_ && theirs.seq != next_seq_)) {
    return;
  }
  next_seq_ = theirs.seq + 1U;
  have_seq_ = true;
  if (pending_count_ < pending_.size()) {
    pending_[pending_count_++] = theirs;
    arrived_ = true;
    newest_ = (theirs.cycle > newest_) ? theirs.cycle : newest_;
  }  // else: a partner more than kHistory cycles ahead of this one: not compared, not arrived
}

void CrossCheck::compare_pending() noexcept {
  std::size_t kept = 0;
  for (std::size_t i = 0; i < pending_count_; ++i) {
    const Digest& theirs = pending_[i];
    if (theirs.cycle > my_cycle_) {
      pending_[kept++] = theirs;  // this channel has not run that cycle yet
      continue;
    }
    const Digest& mine = mine_[theirs.cycle % kHistory];
    const DigestField f = (my_cycle_ - theirs.cycle < kHistory && mine.cycle == theirs.cycle)
                              ? first_difference(mine, theirs)
                              : DigestField::cycle;  // older than this channel remembers
    if (f == DigestField::none) {
      verdict_.differing = 0;
      last_agreed_ = theirs.cycle;
    } else if (++verdict_.differing > limit_ && !verdict_.mismatch) {
      verdict_.mismatch = true;
      verdict_.field = f;
    }
  }
  pending_count_ = kept;
}

CrossVerdict CrossCheck::step(const Digest& mine, Link& link) noexcept {
  mine_[mine.cycle % kHistory] = mine;
  my_cycle_ = mine.cycle;
  link.send(mine);
  arrived_ = false;
  Digest theirs{};
  for (std::size_t k = 0; k < 2U * kHistory && link.receive(theirs); ++k) {
    take(theirs);
  }
  // Missing: none arrived in this cycle, and none of this cycle or later arrived before (a
  // channel catching up after its process was not run reads the partner's digests of several
  // cycles at once; the cycles it then runs are covered by them, not missing).
  verdict_.missing = (arrived_ || newest_ >= my_cycle_) ? 0U : verdict_.missing + 1U;
  if (verdict_.missing >= limit_) {
    verdict_.lost = true;
  }
  compare_pending();
  return verdict_;
}

}  // namespace safestate::controller
