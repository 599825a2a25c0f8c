// Sessions and fan-out (protocol.md "Access and admission", "Fairness").
//
// Decisions where protocol.md is silent:
//  - Frames are read in pieces of at most 4 KiB + 1: a frame over 4 KiB, of whatever
//    size, gets one error TOO_LARGE once it has ended; its bytes are thrown away as they
//    come. Beyond 1 MiB of one frame the error is sent at once and the connection closed.
//  - Outgoing: replies, events and errors queue in order and are all delivered; status
//    has a slot of its own, the newest replacing one not yet written, and goes first
//    when due, so that a burst of events never delays it. A client whose write has made
//    no progress for 5 s (it does not read) is disconnected; so is one with over 32 MiB
//    queued (it reads, but far slower than the cell talks).
//  - A connection that has not said hello within 5 s gets error NOT_HELLO and is closed.
//  - Keep-alive: a ping after 15 s of silence, closed after 30 s without an answer, so a
//    pendant whose network vanished frees the pendant role.
#include "sessions.hpp"

#include <cstdio>

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
void Sessions::prune() {
  std::erase_if(list_, [](const std::weak_ptr<WsSession>& w) {
    const auto s = w.lock();
    return !s || !s->live();
  });
}

bool Sessions::admit() {
  prune();
  if (list_.size() < max_) {
    return true;
  }
  std::shared_ptr<WsSession> oldest;
  for (const auto& w : list_) {
    const auto s = w.lock();
    if (s && !s->hello && (!oldest || s->since() < oldest->since())) {
      oldest = s;
    }
  }
  if (!oldest) {
    return false;  // every slot is a client that said hello
  }
  oldest->evict();
  prune();
  return true;
}

void Sessions::add(const std::shared_ptr<WsSession>& s) { list_.push_back(s); }

void Sessions::shutdown() {
  for (const auto& w : list_) {
    if (auto s = w.lock()) {
      s->shutdown();
    }
  }
}

// ------------------------------------------------------------------ session
WsSession::WsSession(tcp::socket&& socket, Hub& hub)
    : ws_(std::move(socket)), hub_(hub), timer_(ws_.get_executor()), since_(Clock::now()) {
  beast::error_code ec;
  const auto ep = beast::get_lowest_layer(ws_).socket().remote_endpoint(ec);
  loopback_ = !ec && is_loopback(ep.address());
}

WsSession::~WsSession() { leave(); }

void WsSession::run(http::request<http::string_body> req) {
  req_ = std::move(req);
  beast::get_lowest_layer(ws_).expires_never();
  websocket::stream_base::timeout t{};
  t.handshake_timeout = 10s;
  t.idle_timeout = 30s;
  t.keep_alive_pings = true;
  ws_.set_option(t);
  ws_.set_option(websocket::stream_base::decorator(
      [](websocket::response_type& res) { res.set(http::field::server, "safestate"); }));
  ws_.read_message_max(0);  // no limit here: oversize frames are measured and discarded below
  ws_.auto_fragment(false);
  ws_.text(true);
  ws_.async_accept(req_, beast::bind_front_handler(&WsSession::on_accept, shared_from_this()));
}

void WsSession::on_accept(beast::error_code ec) {
  if (ec) {
    abort();
    return;
  }
  open_ = true;
  hub_.attach(*this);
  attached_ = true;
  timer_.expires_after(kHelloDeadline);
  timer_.async_wait(beast::bind_front_handler(&WsSession::on_hello_deadline, shared_from_this()));
  do_read();
}

void WsSession::on_hello_deadline(beast::error_code ec) {
  if (ec || hello || !open_) {
    return;
  }
  hub_.on_hello_timeout(*this);
}

void WsSession::evict() { abort(); }  // not logged: a flood of connections must not flood the log

void WsSession::do_read() {
  if (closing_) {
    return;
  }
  const auto now = Clock::now();
  if (hold_reads_until > now) {
    // Rate limit (protocol.md: a client that keeps sending what it may not): its
    // socket is left unread for a while; TCP flow control slows the sender.
    timer_.expires_at(hold_reads_until);
    timer_.async_wait([self = shared_from_this()](beast::error_code e) {
      if (!e) {
        self->do_read();
      }
    });
    return;
  }
  ws_.async_read_some(buffer_, kMaxFrameBytes + 1U,
                      beast::bind_front_handler(&WsSession::on_read, shared_from_this()));
}

void WsSession::on_read(beast::error_code ec, std::size_t bytes) {
  if (ec) {
    leave();  // closed by the peer, timed out, or aborted
    return;
  }
  message_bytes_ += bytes;
  if (message_bytes_ > kMaxFrameBytes) {
    oversize_ = true;
    buffer_.consume(buffer_.size());
  }
  if (oversize_ && message_bytes_ > kDiscardLimit) {
    hub_.on_too_large(*this, message_bytes_);
    close_after_flush();
    return;
  }
  if (ws_.is_message_done()) {
    message_done();
  }
  do_read();
}

void WsSession::message_done() {
  if (oversize_) {
    hub_.on_too_large(*this, message_bytes_);
  } else if (!ws_.got_text()) {
    hub_.on_binary(*this);
  } else {
    const auto data = buffer_.data();
    hub_.on_text(*this, std::string_view(static_cast<const char*>(data.data()), data.size()));
  }
  buffer_.consume(buffer_.size());
  message_bytes_ = 0;
  oversize_ = false;
}

void WsSession::send(const Frame& frame, bool droppable) {
  if (!open_ || closing_) {
    return;
  }
  const auto now = Clock::now();
  if (writing_ && now - write_since_ > kStallLimit) {
    say("a WebSocket client has not read for 5 s: disconnected");
    abort();
    return;
  }
  if (droppable) {
    status_ = frame;  // replaces an unsent older status
  } else {
    queue_.push_back(frame);
    queued_bytes_ += frame->size();
    if (queued_bytes_ > kMaxQueuedBytes) {
      say("a WebSocket client reads far slower than it is sent to (32 MiB queued): disconnected");
      abort();
      return;
    }
  }
  if (!writing_) {
    do_write();
  }
}

void WsSession::do_write() {
  if (status_) {
    current_ = std::move(status_);
    status_.reset();
  } else {
    current_ = std::move(queue_.front());
    queue_.pop_front();
    queued_bytes_ -= current_->size();
  }
  writing_ = true;
  write_since_ = Clock::now();
  ws_.async_write(asio::buffer(*current_), beast::bind_front_handler(&WsSession::on_write, shared_from_this()));
}

void WsSession::on_write(beast::error_code ec, std::size_t /*bytes*/) {
  writing_ = false;
  current_.reset();
  if (ec || aborted_) {
    abort();
    return;
  }
  if ((status_ || !queue_.empty()) && !closing_) {
    do_write();
  } else if (close_pending_) {
    do_close(close_code_);
  }
}

void WsSession::close_after_flush() { close_when_flushed(websocket::close_code::policy_error); }

void WsSession::close_when_flushed(websocket::close_code code) {
  close_pending_ = true;
  close_code_ = code;
  status_.reset();
  if (!writing_ && queue_.empty()) {
    do_close(code);
  }
}

void WsSession::do_close(websocket::close_code code) {
  if (closing_ || !open_) {
    if (!open_) {
      abort();  // never accepted: nothing to close politely
    }
    return;
  }
  closing_ = true;
  timer_.cancel();
  ws_.async_close(code, [self = shared_from_this()](beast::error_code) {});
}

// The pending read completes with an error and leaves the hub then: never from inside
// a call of the hub, which may be iterating over its clients.
void WsSession::abort() {
  closing_ = true;
  timer_.cancel();
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
