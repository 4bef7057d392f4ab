// The one translation unit that compiles Boost.Beast (view/server.h says what it serves and why).
#include "view/server.h"

#include <algorithm>
#include <chrono>
#include <csignal>
#include <deque>
#include <fstream>
#include <map>
#include <sstream>

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/signal_set.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <nlohmann/json.hpp>

#include "mesh/errors.h"

namespace incise::view {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace asio = boost::asio;
using tcp = asio::ip::tcp;

namespace {

struct PageFile {
  std::string content_type, body;
};

// The page's files: exactly these, nothing else from the disk.
const std::map<std::string, std::pair<std::string, std::string>>& page_files() {
  static const std::map<std::string, std::pair<std::string, std::string>> files = {
      {"/", {"index.html", "text/html; charset=utf-8"}},
      {"/viewer.js", {"viewer.js", "text/javascript; charset=utf-8"}},
      {"/three.module.js", {"three.module.js", "text/javascript; charset=utf-8"}},
      {"/three.core.js", {"three.core.js", "text/javascript; charset=utf-8"}},
      {"/OrbitControls.js", {"OrbitControls.js", "text/javascript; charset=utf-8"}},
  };
  return files;
}

constexpr std::size_t kMaxHeader = 8192;
constexpr std::size_t kMaxBody = 1024;      // the page sends no request bodies
constexpr std::size_t kMaxMessage = 64;     // the largest input is 25 bytes

}  // namespace

class WsSession;

struct ViewServer::Impl : std::enable_shared_from_this<ViewServer::Impl> {
  ViewSource& session;
  ServerOptions opt;
  asio::io_context ioc{1};
  tcp::acceptor acceptor{ioc};
  std::map<std::string, PageFile> files;
  std::vector<std::weak_ptr<WsSession>> pages;
  std::vector<std::string> allowed_hosts;  // Host header values naming this server
  unsigned short port = 0;

  Impl(ViewSource& s, const ServerOptions& o) : session(s), opt(o) {}
  void accept();
  void frame_ready();
  bool host_ok(const http::request<http::string_body>& req) const {
    const std::string host(req[http::field::host]);
    return std::find(allowed_hosts.begin(), allowed_hosts.end(), host) != allowed_hosts.end();
  }
  // A WebSocket may be opened only by this server's own page: Origin http://<Host>.
  bool origin_ok(const http::request<http::string_body>& req) const {
    return host_ok(req) && std::string(req[http::field::origin]) == "http://" + std::string(req[http::field::host]);
  }
  std::size_t live_pages() {
    pages.erase(std::remove_if(pages.begin(), pages.end(), [](const auto& w) { return w.expired(); }), pages.end());
    return pages.size();
  }
};

// One page's WebSocket: inputs in, frames out (one in flight: the next goes when the page
// acknowledges the last, as the newest frame's difference; frames in between are dropped).
class WsSession : public std::enable_shared_from_this<WsSession> {
public:
  WsSession(tcp::socket socket, std::shared_ptr<ViewServer::Impl> srv) : ws_(std::move(socket)), srv_(std::move(srv)) {}

  void run(http::request<http::string_body> req) {
    ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
    ws_.read_message_max(kMaxMessage);
    ws_.async_accept(req, [self = shared_from_this()](beast::error_code ec) {
      if (ec) return;
      self->open_ = true;
      self->last_refill_ = std::chrono::steady_clock::now();
      self->read();
      self->send();
    });
  }

  // Sends what is due: error frames first, then the newest frame if the page is ready for it.
  void send() {
    if (!open_ || writing_) return;
    if (!errors_.empty()) {
      out_text_ = std::move(errors_.front());
      errors_.pop_front();
      ws_.text(true);
      writing_ = true;
      ws_.async_write(asio::buffer(out_text_), [self = shared_from_this()](beast::error_code ec, std::size_t) { self->written(ec); });
      return;
    }
    if (!acked_) return;
    std::shared_ptr<const Snapshot> snap = srv_->session.snapshot();
    if (!snap || snap == sent_) return;
    sent_ = snap;
    out_ = encode(diff(*snap, mirror_));
    acked_ = false;
    ws_.binary(true);
    writing_ = true;
    ws_.async_write(asio::buffer(out_), [self = shared_from_this()](beast::error_code ec, std::size_t) { self->written(ec); });
  }

private:
  void written(beast::error_code ec) {
    writing_ = false;
    if (ec) {
      open_ = false;
      return;
    }
    send();
  }

  void read() {
    ws_.async_read(in_, [self = shared_from_this()](beast::error_code ec, std::size_t) { self->on_read(ec); });
  }

  void error(const std::string& what) {
    // A message may quote a damaged file's bytes: invalid UTF-8 is replaced, not thrown on.
    if (errors_.size() < 16)
      errors_.push_back(nlohmann::json{{"error", what}}.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace));
  }

  // Token bucket: kMaxInputsPerSecond, bursts of as many.
  bool within_rate() {
    const auto now = std::chrono::steady_clock::now();
    tokens_ = std::min(ViewServer::kMaxInputsPerSecond,
                       tokens_ + ViewServer::kMaxInputsPerSecond * std::chrono::duration<double>(now - last_refill_).count());
    last_refill_ = now;
    if (tokens_ < 1) return false;
    tokens_ -= 1;
    return true;
  }

  void on_read(beast::error_code ec) {
    if (ec) {  // closed, or a message above kMaxMessage (Beast fails the read and closes)
      open_ = false;
      return;
    }
    const auto data = in_.cdata();
    const std::span<const std::uint8_t> bytes(static_cast<const std::uint8_t*>(data.data()), data.size());
    if (!within_rate()) {
      error("too many inputs: at most " + std::to_string(int(ViewServer::kMaxInputsPerSecond)) + " a second");
    } else if (!ws_.got_binary()) {
      error("inputs are binary messages (docs/view.md)");
    } else {
      try {
        const InputMessage m = decode_input(bytes);
        if (m.kind == InputKind::Ack) acked_ = true;
        else if (std::string why = srv_->session.post(m); !why.empty()) error(why);
      } catch (const InvalidArgument& e) {
        error(e.what());
      }
    }
    in_.consume(in_.size());
    send();
    read();
  }

  websocket::stream<beast::tcp_stream> ws_;
  std::shared_ptr<ViewServer::Impl> srv_;
  beast::flat_buffer in_;
  std::vector<std::uint8_t> out_;
  std::string out_text_;
  std::deque<std::string> errors_;
  ClientMirror mirror_;
  std::shared_ptr<const Snapshot> sent_;
  bool open_ = false, writing_ = false, acked_ = true;
  double tokens_ = ViewServer::kMaxInputsPerSecond;
  std::chrono::steady_clock::time_point last_refill_;
};

// One HTTP connection: page files, /status, and the upgrade to /ws.
class HttpSession : public std::enable_shared_from_this<HttpSession> {
public:
  HttpSession(tcp::socket socket, std::shared_ptr<ViewServer::Impl> srv) : stream_(std::move(socket)), srv_(std::move(srv)) {}
  void run() { read(); }

private:
  void read() {
    parser_.emplace();
    parser_->header_limit(kMaxHeader);
    parser_->body_limit(kMaxBody);
    stream_.expires_after(std::chrono::seconds(30));
    http::async_read(stream_, buffer_, *parser_,
                     [self = shared_from_this()](beast::error_code ec, std::size_t) { self->on_read(ec); });
  }

  void on_read(beast::error_code ec) {
    if (ec) {
      stream_.socket().shutdown(tcp::socket::shutdown_send, ec);
      return;
    }
    http::request<http::string_body> req = parser_->release();
    if (websocket::is_upgrade(req)) {
      if (req.target() != "/ws") return reply(req, http::status::not_found, "text/plain", "no such socket\n");
      if (!srv_->origin_ok(req)) return reply(req, http::status::forbidden, "text/plain", "origin not allowed\n");
      if (srv_->live_pages() >= std::size_t(ViewServer::kMaxConnections))
        return reply(req, http::status::service_unavailable, "text/plain", "too many pages open\n");
      stream_.expires_never();
      auto ws = std::make_shared<WsSession>(stream_.release_socket(), srv_);
      srv_->pages.push_back(ws);
      ws->run(std::move(req));
      return;
    }
    if (!srv_->host_ok(req)) return reply(req, http::status::forbidden, "text/plain", "host not allowed\n");
    if (req.method() != http::verb::get && req.method() != http::verb::head)
      return reply(req, http::status::method_not_allowed, "text/plain", "GET only\n");
    std::string target(req.target());
    if (const auto q = target.find('?'); q != std::string::npos) target.resize(q);
    if (target == "/status") return reply(req, http::status::ok, "application/json", srv_->session.status_json());
    const auto it = srv_->files.find(target);
    if (it == srv_->files.end()) return reply(req, http::status::not_found, "text/plain", "not found\n");
    reply(req, http::status::ok, it->second.content_type, it->second.body);
  }

  void reply(const http::request<http::string_body>& req, http::status status, const std::string& type, std::string body) {
    auto res = std::make_shared<http::response<http::string_body>>(status, req.version());
    res->set(http::field::server, "incise-view");
    res->set(http::field::content_type, type);
    res->set(http::field::cache_control, "no-store");
    res->set("X-Content-Type-Options", "nosniff");
    res->keep_alive(req.keep_alive() && status == http::status::ok);
    if (req.method() != http::verb::head) res->body() = std::move(body);
    res->prepare_payload();
    http::async_write(stream_, *res, [self = shared_from_this(), res](beast::error_code ec, std::size_t) {
      if (ec || !res->keep_alive()) {
        self->stream_.socket().shutdown(tcp::socket::shutdown_send, ec);
        return;
      }
      self->read();
    });
  }

  beast::tcp_stream stream_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
  std::shared_ptr<ViewServer::Impl> srv_;
};

void ViewServer::Impl::accept() {
  acceptor.async_accept(ioc, [self = shared_from_this()](beast::error_code ec, tcp::socket socket) {
    if (ec == asio::error::operation_aborted) return;
    if (!ec) std::make_shared<HttpSession>(std::move(socket), self)->run();
    self->accept();
  });
}

// From the simulation thread: every page gets the newest frame when it is ready for it.
void ViewServer::Impl::frame_ready() {
  asio::post(ioc, [self = shared_from_this()] {
    for (const auto& w : self->pages)
      if (auto p = w.lock()) p->send();
  });
}

ViewServer::ViewServer(ViewSource& session, const ServerOptions& options)
    : impl_(std::make_shared<Impl>(session, options)) {
  Impl& m = *impl_;
  for (const auto& [target, file] : page_files()) {
    const std::string path = options.web_dir + "/" + file.first;
    std::ifstream in(path, std::ios::binary);
    if (!in)
      throw IoError(path, 0, "cannot read the viewer's page file (run scripts/install-deps.sh, then rebuild)");
    std::ostringstream s;
    s << in.rdbuf();
    m.files[target] = {file.second, s.str()};
  }
  beast::error_code ec;
  const auto address = asio::ip::make_address(options.host, ec);
  if (ec) throw InvalidArgument("--host: '" + options.host + "' is not an IP address");
  const tcp::endpoint ep(address, options.port);
  m.acceptor.open(ep.protocol(), ec);
  if (!ec) m.acceptor.set_option(asio::socket_base::reuse_address(true), ec);
  if (!ec) m.acceptor.bind(ep, ec);
  if (!ec) m.acceptor.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) throw Error("cannot listen on " + options.host + ":" + std::to_string(options.port) + ": " + ec.message());
  m.port = m.acceptor.local_endpoint().port();
  const std::string p = ":" + std::to_string(m.port);
  const std::string h = address.is_v6() ? "[" + options.host + "]" : options.host;
  m.allowed_hosts = {h + p};
  if (address.is_loopback() || address.is_unspecified())
    for (const char* name : {"127.0.0.1", "localhost", "[::1]"}) m.allowed_hosts.push_back(name + p);
  session.set_listener([weak = std::weak_ptr<Impl>(impl_)] {
    if (auto s = weak.lock()) s->frame_ready();
  });
}

ViewServer::~ViewServer() {
  impl_->session.set_listener({});
  stop();
}

std::string ViewServer::url() const {
  const std::string h = impl_->allowed_hosts.front();
  return "http://" + h + "/";
}

void ViewServer::run() {
  asio::signal_set signals(impl_->ioc, SIGINT, SIGTERM);
  signals.async_wait([this](beast::error_code, int) { impl_->ioc.stop(); });
  impl_->accept();
  impl_->ioc.run();
}

void ViewServer::stop() { impl_->ioc.stop(); }

}  // namespace incise::view
