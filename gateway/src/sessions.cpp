// Sessions and fan-out (protocol.md "Access and admission", "Fairness").
//
// Decisions where protocol.md is silent:
//  - Beast performs the opening handshake; then the session frames RFC 6455 itself:
//    every complete message already received is handled in the same turn of the event
//    loop, and the queued frames go out in one gathered write (up to 16 frames / 64 KiB).
//    Pings are answered with pongs, fragmented messages joined, a client's close echoed;
//    an unmasked or malformed frame closes with 1002.
//  - A message over 4 KiB, of whatever size, gets one error TOO_LARGE once it has ended;
//    its bytes are thrown away as they come. Beyond 1 MiB the error is sent at once and
//    the connection closed.
//  - Outgoing: replies, events and errors queue in order and are all delivered; status
//    has a slot of its own, the newest replacing one not yet written, and goes first in
//    the next write, so that a burst of events never delays it. A client whose write has
//    made no progress for 5 s (it does not read) is disconnected; so is one with over
//    32 MiB queued (it reads, but far slower than the cell talks).
//  - A connection that has not said hello within 5 s gets error NOT_HELLO and is closed.
//  - Keep-alive: a ping after 15 s of silence, closed after 30 s without any byte, so a
//    pendant whose network vanished frees the pendant role.
#include "sessions.hpp"

#include <algorithm>
#include <cstdio>
#include <cstring>

namespace safestate::gateway {

namespace {
using namespace std::chrono_literals;
void say(const char* s) { std::fprintf(stderr, "safestate gateway: %s\n", s); }
}  // namespace

bool is_loopback(asio::ip::address a) {
  if (a.is_v6() && a.to_v6().is_v4_mapped()) {
    a = asio::ip::make_address_v4(asio::ip::v4_mapped, a.to_v6());
  }
  return a.is_loopback();
}

// ------------------------------------------------------------------ registry
void Sessions::shutdown() {
  for (const auto& w : list_) {
    if (auto s = w.lock()) {
      s->shutdown();
    }
  }
}

// ------------------------------------------------------------------ session
namespace {
constexpr std::uint8_t kContinuation = 0x0;
constexpr std::uint8_t kText = 0x1;
constexpr std::uint8_t kBinary = 0x2;
constexpr std::uint8_t kClose = 0x8;
constexpr std::uint8_t kPing = 0x9;
constexpr std::uint8_t kPong = 0xA;
// A write holds the status back until it completes (the status goes first in the next
// one). Under test_load (500 observers, a pendant's bursts), a write's completion took about
// 2 ms per frame in it: batches of 50-70 event frames to every observer took 50-220 ms and
// left every observer without status that long (gaps up to 257 ms); at 16 frames the worst
// gap was 61 ms. More writes for a long queue, never a long wait for the status.
constexpr std::size_t kBatchFrames = 16;
constexpr std::size_t kBatchBytes = 64U * 1024U;
constexpr auto kPingAfter = 15s;  // silence, then a ping ...
constexpr auto kIdleLimit = 30s;  // ... and closed without an answer (a vanished pendant frees its role)
constexpr auto kCloseGrace = 2s;  // after our close frame, for the peer's

// The header of an unmasked server frame (RFC 6455 5.2); returns its length.
std::size_t frame_head(std::uint8_t opcode, std::size_t len, std::array<std::uint8_t, 10>& h) {
  h[0] = static_cast<std::uint8_t>(0x80U | opcode);
  if (len < 126U) {
    h[1] = static_cast<std::uint8_t>(len);
    return 2;
  }
  if (len <= 0xFFFFU) {
    h[1] = 126;
    h[2] = static_cast<std::uint8_t>(len >> 8U);
    h[3] = static_cast<std::uint8_t>(len & 0xFFU);
    return 4;
  }
  h[1] = 127;
  for (std::size_t i = 0; i < 8; ++i) {
    h[2 + i] = static_cast<std::uint8_t>((static_cast<std::uint64_t>(len) >> (56U - 8U * i)) & 0xFFU);
  }
  return 10;
}

Frame framed(std::uint8_t opcode, const std::string& payload) {
  std::array<std::uint8_t, 10> h{};
  const std::size_t n = frame_head(opcode, payload.size(), h);
  auto f = std::make_shared<std::string>(reinterpret_cast<const char*>(h.data()), n);
  *f += payload;
  return f;
}
}  // namespace

WsSession::WsSession(tcp::socket&& socket, Hub& hub, Seat seat)
    : ws_(std::move(socket)),
      hub_(hub),
      seat_(std::move(seat)),
      tick_(ws_.get_executor()),
      hold_(ws_.get_executor()),
      since_(Clock::now()) {
  beast::error_code ec;
  const auto ep = beast::get_lowest_layer(ws_).socket().remote_endpoint(ec);
  loopback_ = !ec && is_loopback(ep.address());
}

WsSession::~WsSession() { leave(); }

void WsSession::run(http::request<http::string_body> req) {
  req_ = std::move(req);
  beast::get_lowest_layer(ws_).expires_after(10s);  // the handshake
  ws_.set_option(websocket::stream_base::decorator(
      [](websocket::response_type& res) { res.set(http::field::server, "safestate"); }));
  ws_.async_accept(req_, beast::bind_front_handler(&WsSession::on_accept, shared_from_this()));
}

void WsSession::on_accept(beast::error_code ec) {
  if (ec) {
    abort();
    return;
  }
  beast::get_lowest_layer(ws_).expires_never();
  open_ = true;
  last_read_ = Clock::now();
  hub_.attach(*this);
  attached_ = true;
  arm_tick();
  do_read();
}

void WsSession::arm_tick() {
  tick_.expires_after(1s);
  tick_.async_wait(beast::bind_front_handler(&WsSession::on_tick, shared_from_this()));
}

void WsSession::on_tick(beast::error_code ec) {
  if (ec || aborted_) {
    return;
  }
  const auto now = Clock::now();
  if (!hello && !closing_ && now - since_ >= kHelloDeadline) {
    hub_.on_hello_timeout(*this);  // error NOT_HELLO, then closed
  }
  if (writing_ && now - write_since_ > kStallLimit) {
    say("a WebSocket client has not read for 5 s: disconnected");
    abort();
    return;
  }
  if (now - last_read_ > kIdleLimit || (close_sent_ && now - write_since_ > kCloseGrace)) {
    abort();
    return;
  }
  if (now - last_read_ > kPingAfter && !ping_sent_ && !closing_) {
    ping_sent_ = true;
    queue_control(kPing, {});
  }
  arm_tick();
}

// Not logged: a flood of connections must not flood the log.
void WsSession::evict() { close_try_again_later(); }

void WsSession::shutdown() { close_with(1001); }  // going away

void WsSession::close_after_flush() { close_with(1008); }  // policy violation

void WsSession::close_try_again_later() { close_with(1013); }  // try again later (RFC 6455 7.4.1)

// ------------------------------------------------------------------ reading
void WsSession::do_read() {
  if (reading_ || aborted_) {
    return;
  }
  if (hold_reads_until > Clock::now()) {
    // Rate limit (protocol.md: a client that keeps sending what it may not): its socket
    // is left unread for a while; TCP flow control slows the sender.
    hold_.expires_at(hold_reads_until);
    hold_.async_wait([self = shared_from_this()](beast::error_code e) {
      if (!e) {
        self->do_read();
      }
    });
    return;
  }
  reading_ = true;
  beast::get_lowest_layer(ws_).socket().async_read_some(
      asio::buffer(rbuf_.data() + rlen_, rbuf_.size() - rlen_),
      beast::bind_front_handler(&WsSession::on_read, shared_from_this()));
}

void WsSession::on_read(beast::error_code ec, std::size_t bytes) {
  reading_ = false;
  if (ec) {
    abort();  // closed by the peer, or aborted
    leave();
    return;
  }
  last_read_ = Clock::now();
  ping_sent_ = false;  // it talks: it is alive
  rlen_ += bytes;
  if (!parse()) {
    return;  // protocol error or oversize: closing; nothing more is read
  }
  do_read();
}

// Every complete frame in the buffer, in one go; a frame's payload is consumed as it
// arrives, so a frame of any size needs no more memory than the buffer.
bool WsSession::parse() {
  std::size_t pos = 0;
  bool ok = true;
  while (!aborted_) {
    if (!in_.in_frame) {
      const int h = parse_header(pos);
      if (h == 0) {
        break;  // the rest of the header has not arrived yet
      }
      if (h < 0) {
        ok = false;
        break;
      }
    }
    const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(in_.remaining, rlen_ - pos));
    const bool control = in_.opcode >= kClose;
    for (std::size_t i = 0; i < n; ++i) {
      const char c = static_cast<char>(rbuf_[pos + i] ^ in_.mask[(in_.offset + i) & 3U]);
      if (control) {
        in_.control.push_back(c);
      } else if (!in_.oversize) {
        in_.message.push_back(c);
      }
    }
    if (!control) {
      in_.message_bytes += n;
      if (!in_.oversize && in_.message_bytes > kMaxFrameBytes) {
        in_.oversize = true;
        in_.message.clear();
        in_.message.shrink_to_fit();
      }
    }
    pos += n;
    in_.remaining -= n;
    in_.offset += n;
    if (in_.oversize && in_.message_bytes > kDiscardLimit) {
      hub_.on_too_large(*this, in_.message_bytes);
      close_after_flush();
      return false;
    }
    if (in_.remaining > 0U) {
      break;  // the rest of this frame has not arrived yet
    }
    in_.in_frame = false;
    frame_done();
  }
  std::memmove(rbuf_.data(), rbuf_.data() + pos, rlen_ - pos);
  rlen_ -= pos;
  if (!ok && !closing_) {
    close_with(1002);  // protocol error
  }
  return ok && !aborted_;
}

// 1 parsed, 0 when more bytes are needed, -1 on a protocol error (the caller closes:
// RFC 6455 7.1.7, "fail the WebSocket connection").
int WsSession::parse_header(std::size_t& pos) {
  const std::size_t avail = rlen_ - pos;
  if (avail < 2U) {
    return 0;
  }
  const std::uint8_t b0 = rbuf_[pos];
  const std::uint8_t b1 = rbuf_[pos + 1];
  const std::uint8_t len7 = b1 & 0x7FU;
  const std::size_t ext = (len7 == 126U) ? 2U : (len7 == 127U) ? 8U : 0U;
  if (avail < 2U + ext + 4U) {
    return 0;
  }
  std::uint64_t len = len7;
  if (ext > 0U) {
    len = 0;
    for (std::size_t i = 0; i < ext; ++i) {
      len = (len << 8U) | rbuf_[pos + 2 + i];
    }
  }
  const std::uint8_t opcode = b0 & 0x0FU;
  const bool fin = (b0 & 0x80U) != 0U;
  const bool control = opcode >= kClose;
  const bool bad = (b0 & 0x70U) != 0U || (b1 & 0x80U) == 0U || (len >> 63U) != 0U ||
                   (control && (!fin || len > 125U || opcode > kPong)) || (!control && opcode > kBinary) ||
                   (opcode == kContinuation && in_.message_opcode == 0U) ||
                   ((opcode == kText || opcode == kBinary) && in_.message_opcode != 0U);
  if (bad) {
    return -1;
  }
  for (std::size_t i = 0; i < 4; ++i) {
    in_.mask[i] = rbuf_[pos + 2 + ext + i];
  }
  if (opcode == kText || opcode == kBinary) {
    in_.message_opcode = opcode;
    in_.message_bytes = 0;
    in_.oversize = false;
    in_.message.clear();
  }
  in_.control.clear();
  in_.opcode = opcode;
  in_.fin = fin;
  in_.remaining = len;
  in_.offset = 0;
  in_.in_frame = true;
  pos += 2U + ext + 4U;
  return 1;
}

void WsSession::frame_done() {
  switch (in_.opcode) {
    case kPing: queue_control(kPong, in_.control); return;
    case kPong: return;
    case kClose:
      if (!closing_) {
        closing_ = true;
        queue_.clear();
        queued_bytes_ = 0;
        status_.reset();
        close_frame_ = framed(kClose, in_.control.substr(0, 2));  // echo the code (RFC 6455 5.5.1)
        schedule_write();
      }
      return;
    default: break;
  }
  if (in_.fin) {
    message_done();
  }
}

void WsSession::message_done() {
  const std::uint8_t opcode = in_.message_opcode;
  in_.message_opcode = 0;
  if (closing_) {
    return;  // closing: what else it sends changes nothing
  }
  if (in_.oversize) {
    hub_.on_too_large(*this, in_.message_bytes);
  } else if (opcode == kBinary) {
    hub_.on_binary(*this);
  } else {
    hub_.on_text(*this, in_.message);
  }
  in_.message.clear();
}

// ------------------------------------------------------------------ writing
void WsSession::queue_control(std::uint8_t opcode, std::string payload) {
  if (aborted_ || close_sent_) {
    return;
  }
  control_.push_back(framed(opcode, payload));
  schedule_write();
}

void WsSession::send(const Frame& frame, Delivery delivery) {
  if (!open_ || closing_) {
    return;
  }
  if (writing_ && Clock::now() - write_since_ > kStallLimit) {
    say("a WebSocket client has not read for 5 s: disconnected");
    abort();
    return;
  }
  if (delivery == Delivery::status) {
    status_ = frame;  // replaces an unsent older status
    // The tick queues nothing else for this client: its write starts now (with the events
    // queued for it since its last write), not one posted handler per client later.
    if (!writing_ && !write_posted_) {
      do_write();
    }
    return;
  }
  queue_.push_back(frame);
  queued_bytes_ += frame->size();
  if (queued_bytes_ > kMaxQueuedBytes) {
    say("a WebSocket client reads far slower than it is sent to (32 MiB queued): disconnected");
    abort();
    return;
  }
  if (delivery == Delivery::at_once) {
    schedule_write();
  }
}

// The write starts once the current handler is done, so that every frame queued by it
// (a poll's replies and events, a burst's answers) goes out in one gathered write.
void WsSession::schedule_write() {
  if (writing_ || write_posted_) {
    return;
  }
  write_posted_ = true;
  asio::post(ws_.get_executor(), [self = shared_from_this()] {
    self->write_posted_ = false;
    if (!self->writing_) {
      self->do_write();
    }
  });
}

void WsSession::close_with(std::uint16_t code) {
  if (closing_ || aborted_) {
    return;
  }
  closing_ = true;
  status_.reset();
  if (!open_) {
    abort();  // never accepted: nothing to close politely
    return;
  }
  close_frame_ = framed(kClose, std::string{static_cast<char>(code >> 8U), static_cast<char>(code & 0xFFU)});
  schedule_write();
}

// One gathered write: control frames, then the status when due, then the queue in
// order, then (once the queue is empty) the close frame.
void WsSession::do_write() {
  if (aborted_ || close_sent_) {
    return;
  }
  batch_.clear();
  heads_.clear();
  buffers_.clear();
  std::vector<std::size_t> head_len;
  std::size_t bytes = 0;
  auto add = [&](Frame f, bool raw) {
    bytes += f->size();
    heads_.emplace_back();
    head_len.push_back(raw ? 0U : frame_head(kText, f->size(), heads_.back()));
    batch_.push_back(std::move(f));
  };
  while (!control_.empty()) {
    add(std::move(control_.front()), true);
    control_.pop_front();
  }
  if (status_) {
    add(std::move(status_), false);
    status_.reset();
  }
  while (!queue_.empty() && batch_.size() < kBatchFrames && bytes < kBatchBytes) {
    queued_bytes_ -= queue_.front()->size();
    add(std::move(queue_.front()), false);
    queue_.pop_front();
  }
  if (queue_.empty() && close_frame_) {
    add(std::move(close_frame_), true);
    close_frame_.reset();
    close_sent_ = true;
  }
  if (batch_.empty()) {
    return;
  }
  for (std::size_t i = 0; i < batch_.size(); ++i) {  // heads_ no longer grows: its addresses hold
    if (head_len[i] > 0U) {
      buffers_.emplace_back(heads_[i].data(), head_len[i]);
    }
    buffers_.emplace_back(batch_[i]->data(), batch_[i]->size());
  }
  writing_ = true;
  write_since_ = Clock::now();
  asio::async_write(beast::get_lowest_layer(ws_).socket(), buffers_,
                    beast::bind_front_handler(&WsSession::on_write, shared_from_this()));
}

void WsSession::on_write(beast::error_code ec, std::size_t /*bytes*/) {
  writing_ = false;
  batch_.clear();
  if (ec || aborted_) {
    abort();
    return;
  }
  if (close_sent_) {
    beast::error_code e;
    beast::get_lowest_layer(ws_).socket().shutdown(tcp::socket::shutdown_send, e);
    return;  // the peer's close (or EOF) ends the read; the tick gives up after 2 s
  }
  do_write();
}

// The pending read completes with an error and leaves the hub then: never from inside
// a call of the hub, which may be iterating over its clients.
void WsSession::abort() {
  closing_ = true;
  tick_.cancel();
  hold_.cancel();
  if (!writing_) {
    queue_.clear();
    queued_bytes_ = 0;
  }
  if (!aborted_) {
    aborted_ = true;
    beast::error_code ec;
    beast::get_lowest_layer(ws_).socket().close(ec);
  }
}

void WsSession::leave() {
  open_ = false;
  aborted_ = true;
  if (attached_) {
    attached_ = false;
    hub_.detach(*this);
  }
}

}  // namespace safestate::gateway
