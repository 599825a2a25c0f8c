// The protocol's client messages (protocol.md "Messages", "Roles", "Bad input",
// "Access and admission"): hello, command and sim, answered here or passed to the core.
//
// Decisions where protocol.md is silent:
//  - hello: credentials first (admission.cpp), then the role. A refused hello
//    (BAD_TOKEN, ROLE_TAKEN) leaves the connection as it was (not hello'd: the 5 s
//    deadline still runs), so the client may retry, e.g. as an observer. A second hello
//    changes the role. After `welcome` the client gets one status message at once.
//  - The pendant's slot: at most max_clients - 1 clients may be hello'd as anything but
//    the pendant; one more gets ROLE_TAKEN ("the last slot is kept for the pendant") and
//    is closed with 1013 "try again later" (a client with back-off returns later).
//  - A command before hello gets NOT_HELLO. An observer's command is answered
//    NOT_CONTROL_OWNER here: it never reaches the core nor the event log. Beyond
//    kMaxRefusedPerSecond such refusals in a second, the client's socket is not read
//    until the second is over (every command still gets its one reply, later).
//  - sim needs a hello'd loopback peer and a simulated cell, else NOT_HELLO /
//    NOT_SIMULATED. With kMaxPendingPerClient records in flight, or beyond
//    kMaxRecordsPerSecond sustained (a token bucket of kMaxPendingPerClient), a client
//    gets reply QUEUE_FULL from the gateway (also for sim).
//  - Refused frames (error messages) are counted per client; kMaxBadFrames in a row
//    close the connection after the last error is sent. Any accepted message resets the
//    count.
#include "safestate/gateway/hub.hpp"

#include <algorithm>

namespace safestate::gateway {

void Hub::attach(Client& c) {
  c.id = ++next_client_id_;
  clients_[c.id] = &c;
}

void Hub::detach(Client& c) {
  clients_.erase(c.id);
  if (pendant_ == c.id) {
    pendant_ = 0;
  }
}

void Hub::send(Client& c, const Json& message) { c.send(std::make_shared<const std::string>(dump(message)), Delivery::at_once); }

void Hub::refuse(Client& c, ErrorCode code, const std::string& detail) {
  send(c, make_error(code, detail));
  if (++c.bad_frames >= kMaxBadFrames) {
    c.close_after_flush();
  }
}

void Hub::on_text(Client& c, std::string_view text) {
  ClientMessage msg = parse_client_message(text);
  if (auto* e = std::get_if<ProtocolError>(&msg)) {
    refuse(c, e->code, e->detail);
  } else if (auto* h = std::get_if<HelloMsg>(&msg)) {
    on_hello(c, *h);
  } else if (auto* m = std::get_if<CommandMsg>(&msg)) {
    on_command(c, *m);
  } else if (auto* s = std::get_if<SimMsg>(&msg)) {
    on_sim(c, *s);
  }
}

void Hub::on_binary(Client& c) { refuse(c, ErrorCode::BAD_MESSAGE, "binary frames are not accepted: send JSON text"); }

void Hub::on_too_large(Client& c, std::size_t bytes) {
  refuse(c, ErrorCode::TOO_LARGE,
         "frame of " + std::to_string(bytes) + " bytes; the limit is " + std::to_string(kMaxFrameBytes));
}

void Hub::on_hello_timeout(Client& c) {
  send(c, make_error(ErrorCode::NOT_HELLO, "no hello within 5 s: closed"));
  c.close_after_flush();
}

std::size_t Hub::hello_others() const {
  std::size_t n = 0;
  for (const auto& [id, c] : clients_) {
    n += (c->hello && id != pendant_) ? 1U : 0U;
  }
  return n;
}

void Hub::on_hello(Client& c, const HelloMsg& h) {
  if (const std::string why = access_.hello_refusal(h.role, h.has_token, h.token); !why.empty()) {
    refuse(c, ErrorCode::BAD_TOKEN, why);
    return;
  }
  if (h.role == Role::pendant && pendant_ != 0 && pendant_ != c.id) {
    refuse(c, ErrorCode::ROLE_TAKEN, "another pendant is connected (single point of control)");
    return;
  }
  const bool takes_other_slot = h.role != Role::pendant && (!c.hello || pendant_ == c.id);
  if (takes_other_slot && hello_others() + 1U >= options_.max_clients) {
    send(c, make_error(ErrorCode::ROLE_TAKEN, "the server is full: its last slot is kept for the pendant"));
    c.close_try_again_later();
    return;
  }
  if (pendant_ == c.id && h.role != Role::pendant) {
    pendant_ = 0;
  }
  c.hello = true;
  c.role = h.role;
  c.name = h.client;
  c.bad_frames = 0;
  if (h.role == Role::pendant) {
    pendant_ = c.id;
  }
  send(c, make_welcome(h.role, options_.version));
  read_status();
  send(c, status_json(status_, extras(), true));
  c.status_t = status_.t;
  c.status_at = Clock::now();
}

void Hub::refuse_command(Client& c, const Json& client_seq) {
  local_reply(c, client_seq, core::Result::NOT_CONTROL_OWNER);
  const auto now = Clock::now();
  if (now - c.refused_window >= std::chrono::seconds(1)) {
    c.refused_window = now;
    c.refused = 0;
  }
  if (++c.refused >= kMaxRefusedPerSecond) {
    c.hold_reads_until = c.refused_window + std::chrono::seconds(1);
  }
}

void Hub::on_command(Client& c, const CommandMsg& m) {
  if (!c.hello) {
    refuse(c, ErrorCode::NOT_HELLO, "send hello before commands");
    return;
  }
  c.bad_frames = 0;
  if (c.role == Role::observer) {
    refuse_command(c, m.seq);  // read only (protocol.md "Roles"): never reaches the core
    return;
  }
  bridge::CommandRecord rec{};
  rec.kind = bridge::RecordKind::command;
  rec.command = m.command;
  rec.command.source = static_cast<std::uint8_t>(source_of(c.role));
  submit(c, rec, m.seq, false, m.name);
}

void Hub::on_sim(Client& c, const SimMsg& m) {
  if (!c.loopback_peer()) {
    refuse(c, ErrorCode::NOT_SIMULATED, "sim messages are accepted only from a loopback client");
    return;
  }
  if (!c.hello) {
    refuse(c, ErrorCode::NOT_HELLO, "send hello before sim messages");
    return;
  }
  if (segment_.header().simulated.load(std::memory_order_relaxed) == 0U) {
    refuse(c, ErrorCode::NOT_SIMULATED, "the cell is not simulated");
    return;
  }
  c.bad_frames = 0;
  submit(c, m.record, m.seq, true, {});
}

std::uint32_t Hub::next_seq() {
  do {
    ++next_seq_;
  } while (next_seq_ == 0U || pending_.count(next_seq_) != 0U);  // 0 is the reset button's
  return next_seq_;
}

void Hub::local_reply(Client& c, const Json& client_seq, core::Result r) {
  ++commands_by_result_[static_cast<std::size_t>(r)];
  send(c, make_reply(client_seq, core::to_string(r)));
}

bool Hub::take_token(Client& c) {
  const auto now = Clock::now();
  if (c.bucket_at != Clock::time_point{}) {
    const double refill = std::chrono::duration<double>(now - c.bucket_at).count() * kMaxRecordsPerSecond;
    c.bucket = std::min(static_cast<double>(kMaxPendingPerClient), c.bucket + refill);
  }
  c.bucket_at = now;
  if (c.bucket < 1.0) {
    return false;
  }
  c.bucket -= 1.0;
  return true;
}

void Hub::submit(Client& c, bridge::CommandRecord record, const Json& client_seq, bool sim, const std::string& name) {
  if (c.pending >= kMaxPendingPerClient || !take_token(c)) {
    local_reply(c, client_seq, core::Result::QUEUE_FULL);
    return;
  }
  record.seq = next_seq();
  record.command.seq = record.seq;
  if (!segment_.commands().push(record)) {
    local_reply(c, client_seq, core::Result::QUEUE_FULL);
    return;
  }
  ++c.pending;
  Pending p;
  p.client = c.id;
  p.seq = client_seq;
  p.sim = sim;
  p.since = Clock::now();
  if (!sim && record.command.id == static_cast<std::uint8_t>(core::CommandId::validate_config)) {
    p.validate = true;
    p.code = record.command.code;
    p.client_name = c.name;
    p.role = c.role;
  }
  pending_[record.seq] = std::move(p);
  if (on_submit_) {
    on_submit_();
  }
  if (!sim) {
    recent_[record.seq] = Recent{client_seq, name};
    recent_order_.push_back(record.seq);
    while (recent_order_.size() > kRecentMax) {
      recent_.erase(recent_order_.front());
      recent_order_.pop_front();
    }
  }
}

}  // namespace safestate::gateway
