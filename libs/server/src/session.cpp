// v4r - robust model-based object tracking. MIT licence.
#include "session.hpp"

#include <algorithm>

#include <fmt/format.h>

#include "v4r/core/log.hpp"

namespace v4r::server {

namespace code = protocol::code;
using protocol::format_err;
using protocol::format_ok;

namespace {

template <class... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};
template <class... Ts>
Overloaded(Ts...) -> Overloaded<Ts...>;

/// Compares in time independent of where the strings differ (token checks).
bool same_secret(std::string_view a, std::string_view b) {
  unsigned char diff = a.size() == b.size() ? 0 : 1;
  const std::size_t n = std::max(a.size(), b.size());
  for (std::size_t i = 0; i < n; ++i) {
    const unsigned char x = i < a.size() ? static_cast<unsigned char>(a[i]) : 0;
    const unsigned char y = i < b.size() ? static_cast<unsigned char>(b[i]) : 0;
    diff |= static_cast<unsigned char>(x ^ y);
  }
  return diff == 0;
}

constexpr int kMaxAuthFailures = 3;  // wrong tokens before the connection is closed

/// The ERR reply of a model that could not be loaded (the error's field holds the code).
std::string model_error(Error e) {
  const std::string c = e.field.empty() ? std::string(code::kBadModel) : e.field;
  e.field.clear();
  return format_err("AddModel", c, e.to_string());
}

}  // namespace

Session::Session(asio::ip::tcp::socket socket, SessionHost& host)
    : host_(host),
      socket_(std::move(socket)),
      write_timer_(host.io()),
      auth_timer_(host.io()),
      outbox_(host.options().max_replies, host.options().event_backlog) {
  asio::error_code ignored;
  socket_.set_option(asio::ip::tcp::no_delay(true), ignored);
  auth_required_ = !host.options().token.empty();
}

void Session::start() {
  reply(protocol::hello(auth_required_));
  if (auth_required_) {
    auth_timer_.expires_after(host_.options().auth_timeout);
    auth_timer_.async_wait([w = weak_from_this()](const asio::error_code& ec) {
      auto s = w.lock();
      if (ec || !s || s->authed_ || s->closed_ || s->closing_) return;
      s->reply(format_err("?", code::kUnauthorized, "no Auth within the time allowed"));
      s->closing_ = true;
      s->flush();
    });
  }
  start_read();
}

void Session::refuse(std::string_view why) {
  reply(format_err("?", code::kBusy, why));
  closing_ = true;
  flush();
}

void Session::start_read() {
  if (reading_ || closed_ || closing_) return;
  reading_ = true;
  socket_.async_read_some(asio::buffer(chunk_), [self = shared_from_this()](const asio::error_code& ec, std::size_t n) {
    self->on_read(ec, n);
  });
}

void Session::on_read(const asio::error_code& ec, std::size_t n) {
  reading_ = false;
  if (closed_) return;
  if (ec) {
    // Disconnected (or reset): whatever was cut off (a partial line or payload) is not applied.
    if (payload_cmd_ && !shut_down_)
      V4R_LOG_WARN("v4r serve: AddModel object={}: payload cut off ({} of {} bytes missing), not applied",
                   payload_cmd_->object, framer_.payload_remaining(), payload_cmd_->bytes);
    close();
    return;
  }
  if (shut_down_) {
    drain();  // closing: input is read and dropped until the client closes
    return;
  }
  framer_.feed(std::string_view(chunk_.data(), n));
  process();
}

void Session::process() {
  while (!busy_ && !closing_ && !closed_) {
    auto frame = framer_.next();
    if (!frame) break;
    std::visit(Overloaded{[&](protocol::Framer::Line& l) { handle_line(l.text); },
                          [&](protocol::Framer::Overlong& o) { reply(format_err(o.error)); },
                          [&](protocol::Framer::Payload& p) { handle_payload(std::move(p.bytes)); }},
               *frame);
  }
  if (!busy_ && !closing_ && !closed_) start_read();
}

void Session::handle_line(std::string_view line) {
  auto r = protocol::parse(line);
  if (const auto* e = std::get_if<protocol::ParseError>(&r)) {
    if (e->skip_bytes > 0) framer_.expect_payload(e->skip_bytes, false);
    if (e->code == code::kEmptyLine) return;  // blank lines get no reply
    reply(format_err(*e));
    if (e->code == code::kTooLarge) {
      // Where the announced payload ends cannot be known: the stream is lost.
      closing_ = true;
      flush();
    }
    return;
  }
  const protocol::Command& cmd = std::get<protocol::Command>(r);
  if (auth_required_ && !authed_ && !std::holds_alternative<protocol::Auth>(cmd)) {
    if (const std::size_t n = protocol::payload_bytes(cmd); n > 0) framer_.expect_payload(n, false);
    reply(format_err(protocol::command_name(cmd), code::kUnauthorized, "send Auth token=... first"));
    return;
  }
  if (const auto* m = std::get_if<protocol::AddModelInline>(&cmd)) {
    if (!host_.reserve_payload(m->bytes)) {
      framer_.expect_payload(m->bytes, false);
      reply(format_err("AddModel", code::kBusy, "too many models being uploaded at once; try again"));
      return;
    }
    payload_cmd_ = *m;
    framer_.expect_payload(m->bytes, true);
    return;
  }
  handle_command(cmd);
}

TrackingService::ReplyFn Session::deferred_reply() {
  busy_ = true;
  return [w = weak_from_this(), &io = host_.io()](std::string line) {
    asio::post(io, [w, line = std::move(line)]() mutable {
      if (auto s = w.lock()) s->finish_command(std::move(line));
    });
  };
}

void Session::finish_command(std::string line) {
  busy_ = false;
  if (closed_) return;
  reply(std::move(line));
  process();
}

void Session::handle_payload(std::string bytes) {
  if (!payload_cmd_) return;
  protocol::AddModelInline cmd = std::move(*payload_cmd_);
  payload_cmd_.reset();
  auto done = deferred_reply();
  TrackingService& service = host_.service();
  SessionHost& host = host_;
  host_.loader().post([cmd = std::move(cmd), text = std::move(bytes), done = std::move(done), &service, &host]() mutable {
    Expected<std::shared_ptr<const model::Model>> m = make_error("not loaded");
    try {
      m = load_model_text(text, cmd.format, fmt::format("<AddModel object={}>", cmd.object), host.data_dirs(), cmd.scale);
    } catch (const std::exception& e) {  // e.g. out of memory in a parser: this request fails, the server goes on
      m = Unexpected{Error{fmt::format("<AddModel object={}>: {}", cmd.object, e.what()), {}, 0, 0, std::string(code::kInternal)}};
    }
    std::string().swap(text);
    host.release_payload(cmd.bytes);
    if (!m) {
      done(model_error(m.error()));
      return;
    }
    service.submit(ModelReady{cmd.object, std::move(*m)}, std::move(done));
  });
}

void Session::handle_command(const protocol::Command& cmd) {
  std::visit(
      Overloaded{
          [&](const protocol::Ping&) { reply(format_ok("Ping")); },
          [&](const protocol::Quit&) {
            reply(format_ok("Quit"));
            closing_ = true;
            flush();
          },
          [&](const protocol::Auth& a) {
            if (!auth_required_ || same_secret(a.token, host_.options().token)) {
              authed_ = true;
              auth_timer_.cancel();
              reply(format_ok("Auth"));
              return;
            }
            reply(format_err("Auth", code::kUnauthorized, "wrong token"));
            if (++auth_failures_ >= kMaxAuthFailures) {
              closing_ = true;
              flush();
            }
          },
          [&](const protocol::Subscribe& s) {
            Subscription& sub = s.what == protocol::Topic::kObjectPose ? pose_sub_ : status_sub_;
            sub.on = true;
            sub.interval_s = s.rate_hz > 0.0 ? 1.0 / s.rate_hz : 0.0;
            sub.sent_any = false;
            std::string extra = fmt::format("what={}", protocol::to_string(s.what));
            if (s.rate_hz > 0.0) extra += " rate=" + protocol::format_number(s.rate_hz);
            reply(format_ok("Subscribe", extra));
          },
          [&](const protocol::Unsubscribe& s) {
            const bool pose = s.what == protocol::Topic::kObjectPose;
            (pose ? pose_sub_ : status_sub_).on = false;
            outbox_.drop_events(pose ? "P " : "S");
            reply(format_ok("Unsubscribe", fmt::format("what={}", protocol::to_string(s.what))));
          },
          [&](const protocol::AddModelPath& p) {
            auto done = deferred_reply();
            TrackingService& service = host_.service();
            const PathPolicy& data = host_.data_dirs();
            host_.loader().post([p, done = std::move(done), &service, &data]() mutable {
              Expected<std::shared_ptr<const model::Model>> m = make_error("not loaded");
              try {
                m = load_model_path(p.path, p.format, data, p.scale);
              } catch (const std::exception& e) {
                m = Unexpected{Error{fmt::format("{}: {}", p.path, e.what()), {}, 0, 0, std::string(code::kInternal)}};
              }
              if (!m) {
                done(model_error(m.error()));
                return;
              }
              service.submit(ModelReady{p.object, std::move(*m)}, std::move(done));
            });
          },
          [&](const protocol::AddObject& a) {
            if (!a.connection_lifetime) {
              host_.service().submit(cmd, deferred_reply());
              return;
            }
            // Owned by this connection once the service said OK (recorded on the network thread).
            host_.service().submit(cmd, [done = deferred_reply(), w = weak_from_this(), &io = host_.io(),
                                         name = a.name](std::string line) mutable {
              if (line.rfind("OK ", 0) == 0)
                asio::post(io, [w, name]() {
                  if (auto s = w.lock()) s->owned_.push_back(name);
                });
              done(std::move(line));
            });
          },
          [&](const protocol::RemoveObject& r) {
            std::erase(owned_, r.name);
            host_.service().submit(cmd, deferred_reply());
          },
          [&](const auto&) { host_.service().submit(cmd, deferred_reply()); },
      },
      cmd);
}

void Session::reply(std::string line) {
  if (closed_) return;
  line.push_back('\n');
  if (!outbox_.push_reply(std::make_shared<const std::string>(std::move(line)))) {
    drop_slow("too many unread replies: disconnecting");
    return;
  }
  flush();
}

void Session::drop_slow(std::string_view why) {
  if (closing_) return;
  // The client does not read (its replies pile up, or a write made no progress for
  // write_stall_timeout): drop it, with a last word it gets if it reads within close_grace.
  slow_ = true;
  closing_ = true;
  host_.dropping_slow_client();
  outbox_ = Outbox(host_.options().max_replies, 1);
  std::string last = format_err("?", code::kBusy, why) + "\n";
  outbox_.push_reply(std::make_shared<const std::string>(std::move(last)));
  if (writing_) {
    arm_write_timer(host_.options().close_grace);
  } else {
    flush();
  }
}

bool Session::accept(Subscription& s, double stamp) {
  if (!s.on) return false;
  if (s.interval_s > 0.0 && s.sent_any && stamp - s.last_stamp < s.interval_s * (1.0 - 1e-6)) return false;
  s.last_stamp = stamp;
  s.sent_any = true;
  return true;
}

void Session::deliver(const FrameEvents& ev) {
  if (closed_ || closing_) return;
  bool any = false;
  if (accept(pose_sub_, ev.stamp_s)) {
    for (std::size_t i = 0; i < ev.poses.size(); ++i) outbox_.put_event("P " + ev.poses[i].object, ev.pose_lines[i]);
    any = !ev.poses.empty();
  }
  if (accept(status_sub_, ev.stamp_s)) {
    outbox_.put_event("S", ev.status_line);
    any = true;
  }
  if (any) flush();
}

void Session::flush() {
  if (writing_ || closed_) return;
  sending_.clear();
  outbox_.take(sending_);
  if (sending_.empty()) {
    if (closing_) close_gracefully();
    return;
  }
  buffers_.clear();
  std::size_t bytes = 0;
  for (const SharedLine& l : sending_) {
    buffers_.emplace_back(asio::buffer(*l));
    bytes += l->size();
  }
  host_.note_write(sending_.size(), bytes);
  writing_ = true;
  const std::uint64_t gen = ++write_gen_;
  arm_write_timer(closing_ ? host_.options().close_grace : host_.options().write_stall_timeout);
  asio::async_write(socket_, buffers_, [self = shared_from_this(), gen](const asio::error_code& ec, std::size_t) {
    self->on_written(ec, gen);
  });
}

void Session::arm_write_timer(std::chrono::milliseconds d) {
  write_timer_.expires_after(d);
  write_timer_.async_wait([w = weak_from_this(), gen = write_gen_](const asio::error_code& ec) {
    auto s = w.lock();
    if (ec || !s || s->closed_ || !s->writing_ || s->write_gen_ != gen) return;
    if (!s->closing_) {
      // The client has not taken this write for the whole deadline: it does not read.
      s->drop_slow("not reading: no write progress for the write stall timeout; disconnecting");
      return;
    }
    // Closing, and the last words were not taken within close_grace either.
    s->slow_ = true;
    s->close();
  });
}

void Session::on_written(const asio::error_code& ec, std::uint64_t gen) {
  if (gen != write_gen_) return;
  writing_ = false;
  write_timer_.cancel();
  if (closed_) return;
  if (ec) {
    close();
    return;
  }
  flush();
}

void Session::close_gracefully() {
  if (closed_ || shut_down_) return;
  // Send FIN, then read until the client closes too (bounded by close_grace), so that
  // unread input does not turn the close into a reset that could destroy our last reply.
  shut_down_ = true;
  release();  // the client's slot is free from now on
  asio::error_code ignored;
  socket_.shutdown(asio::ip::tcp::socket::shutdown_send, ignored);
  write_timer_.expires_after(host_.options().close_grace);
  write_timer_.async_wait([w = weak_from_this()](const asio::error_code& ec) {
    if (auto s = w.lock(); s && !ec) s->close();
  });
  drain();
}

void Session::drain() {
  if (closed_ || reading_) return;
  reading_ = true;
  socket_.async_read_some(asio::buffer(chunk_), [self = shared_from_this()](const asio::error_code& ec, std::size_t n) {
    self->on_read(ec, n);
  });
}

void Session::close() {
  if (closed_) return;
  closed_ = true;
  asio::error_code ignored;
  socket_.shutdown(asio::ip::tcp::socket::shutdown_both, ignored);
  socket_.close(ignored);
  write_timer_.cancel();
  auth_timer_.cancel();
  if (payload_cmd_) {  // a payload cut off: its reservation goes back
    host_.release_payload(payload_cmd_->bytes);
    payload_cmd_.reset();
  }
  for (std::string& name : owned_) host_.service().submit(protocol::Command{protocol::RemoveObject{std::move(name)}}, [](std::string) {});
  owned_.clear();
  release();
}

void Session::release() {
  if (released_) return;
  released_ = true;
  host_.session_closed(shared_from_this());
}

}  // namespace v4r::server
