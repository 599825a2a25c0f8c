// Client-to-server messages of protocol.md, parsed and checked, without any network:
// what a WebSocket frame asks for, or why it is refused. The core judges commands
// itself (SPEC §5): an unknown name or a bad argument is still encoded, with an invalid
// value, so that the core answers UNKNOWN_COMMAND / BAD_ARGUMENT. Only a frame whose
// `seq` cannot be read (or that is not a command at all) is refused here.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <variant>

#include <nlohmann/json.hpp>

#include "safestate/gateway/bridge.hpp"
#include "safestate/core/types.hpp"

namespace safestate::gateway {

using Json = nlohmann::ordered_json;

// The largest frame a client may send (protocol.md "Bad input").
inline constexpr std::size_t kMaxFrameBytes = 4096;

enum class Role : std::uint8_t { pendant, remote, observer };
const char* to_string(Role r) noexcept;
core::Source source_of(Role r) noexcept;

// Error codes of the `error` message.
enum class ErrorCode : std::uint8_t { BAD_MESSAGE, NOT_HELLO, ROLE_TAKEN, BAD_TOKEN, TOO_LARGE, NOT_SIMULATED };
const char* to_string(ErrorCode c) noexcept;

struct HelloMsg {
  Role role = Role::observer;
  std::string client;
  std::string token;
  bool has_token = false;
};

struct CommandMsg {
  Json seq;          // the client's seq, echoed verbatim in the reply
  std::string name;  // as sent ("" when missing), for the event log
  core::Command command{};  // id/axis/dir/speed/mode; seq and source are set by the session
};

struct SimMsg {
  Json seq;
  bridge::CommandRecord record{};  // kind sim_set, sim_fault or sim_person; seq set by the session
};

struct ProtocolError {
  ErrorCode code = ErrorCode::BAD_MESSAGE;
  std::string detail;
};

using ClientMessage = std::variant<ProtocolError, HelloMsg, CommandMsg, SimMsg>;

// One text frame -> one message, or the error to answer.
ClientMessage parse_client_message(std::string_view text);

// The scenario vocabulary of `in` and `fault` lines (spec/scenario-format.md), as used
// by the `sim` message. Return "" on success, else what is wrong.
std::string encode_sim_set(const Json& set, bridge::CommandRecord& out);
std::string encode_sim_fault(std::string_view line, bridge::CommandRecord& out);
// SPEC §11, the simulated person (an extension of the `sim` message, docs/collaborative.md):
// "stand", "leave", or {"at": [X, Y], "radius_mm": R, "walk": [[X, Y, SPEED(, STAND_MS)], ...],
// "fields": [OUTER, INNER]} with the limits of the scenario's `person` keys. On a problem
// `out` is left without any action.
std::string encode_sim_person(const Json& person, bridge::CommandRecord& out);

// Server-to-client messages.
Json make_welcome(Role role, const std::string& version);
Json make_reply(const Json& seq, const char* result);
Json make_error(ErrorCode code, const std::string& detail);

}  // namespace safestate::gateway
