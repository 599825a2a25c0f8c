// libFuzzer target: the gateway's client-message parser on arbitrary frames. It must
// never crash, and whatever it accepts must be well-formed for the bridge.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "safestate/gateway/protocol.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace safestate;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const gateway::ClientMessage m = gateway::parse_client_message(text);
  if (const auto* c = std::get_if<gateway::CommandMsg>(&m)) {
    if (c->command.id > core::kCommandCount) __builtin_trap();  // unknown = exactly kCommandCount
  }
  if (const auto* s = std::get_if<gateway::SimMsg>(&m)) {
    if (s->record.kind == bridge::RecordKind::command) __builtin_trap();
    if (s->record.kind == bridge::RecordKind::sim_set && (s->record.set_mask >> bridge::kContactCount) != 0U) __builtin_trap();
    // A person record the gateway accepts does something, with at most 16 points (the walk's array).
    if (s->record.kind == bridge::RecordKind::sim_person &&
        (s->record.person.what == 0U || s->record.person.points > bridge::kPersonPoints)) __builtin_trap();
  }
  return 0;
}
