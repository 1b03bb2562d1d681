// The preview page's HTTP loop: see http_loop.h.

#include "cli/http_loop.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <deque>
#include <string_view>

#include "core/error.h"

namespace spangle {

using Clock = std::chrono::steady_clock;

/** One client socket and what waits to be read from and sent to it. */
struct HttpLoop::Connection {
    int fd = -1;                                         ///< non-blocking socket, owned
    std::string in;                                      ///< received bytes not yet answered
    std::deque<std::shared_ptr<const std::string>> out;  ///< waiting to be sent, in order
    std::size_t front_sent = 0;                          ///< bytes of out.front() already sent
    std::size_t queued = 0;                              ///< unsent bytes in out
    bool stream = false;              ///< an event stream: reads nothing more, gets news
    bool close_when_sent = false;     ///< close once out is empty (Connection: close, errors)
    StreamCursor cursor{};            ///< an event stream's position (the owner's)
    Clock::time_point moved;          ///< last time bytes were sent, or out became non-empty
    Clock::time_point active;         ///< last time bytes were received or a response ended
    Clock::time_point request_start;  ///< when the first byte of the pending request came

    ~Connection() {
        if (fd >= 0) ::close(fd);
    }
    void send(std::shared_ptr<const std::string> text, Clock::time_point now) {
        if (!text || text->empty()) return;
        if (queued == 0) moved = now;
        queued += text->size();
        out.push_back(std::move(text));
    }
    bool idle() const { return !stream && in.empty() && queued == 0; }
};

namespace {

/** `s` as an immutable shared buffer. */
std::shared_ptr<const std::string> shared(std::string s) {
    return std::make_shared<const std::string>(std::move(s));
}

const char* reason(int status) {
    switch (status) {
        case 200:
            return "OK";
        case 400:
            return "Bad Request";
        case 403:
            return "Forbidden";
        case 404:
            return "Not Found";
        case 405:
            return "Method Not Allowed";
        case 431:
            return "Request Header Fields Too Large";
        case 503:
            return "Service Unavailable";
        default:
            return "Error";
    }
}

/** The head of a reply with a body of `length` bytes. */
std::string head(const HttpReply& r, std::size_t length, bool keep_alive) {
    return fmt::format(
        "HTTP/1.1 {} {}\r\nContent-Type: {}\r\nContent-Length: {}\r\nCache-Control: no-store\r\n"
        "Connection: {}\r\n{}\r\n",
        r.status, reason(r.status), r.content_type, length, keep_alive ? "keep-alive" : "close",
        r.headers);
}

/** A plain-text reply. */
HttpReply text_reply(int status, std::string text, std::string headers = {}) {
    HttpReply r;
    r.status = status;
    r.body = shared(std::move(text));
    r.headers = std::move(headers);
    return r;
}

bool iequals(std::string_view a, std::string_view b) {
    return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
               return std::tolower(static_cast<unsigned char>(x)) ==
                      std::tolower(static_cast<unsigned char>(y));
           });
}

std::string_view trim(std::string_view s) {
    while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
    while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r'))
        s.remove_suffix(1);
    return s;
}

/** A request's head (up to its blank line), parsed. */
struct ParsedHead {
    HttpRequest request;
    bool valid = false;      ///< a request line and headers as HTTP/1.x has them
    bool keep_alive = true;  ///< HTTP/1.1 unless "Connection: close"; HTTP/1.0 if asked
    bool has_body = false;   ///< Content-Length > 0 or Transfer-Encoding: not read here
};

ParsedHead parse_head(std::string_view text) {
    ParsedHead p;
    std::size_t eol = text.find("\r\n");
    const std::string_view line = text.substr(0, eol);
    const std::size_t s1 = line.find(' '), s2 = line.rfind(' ');
    if (s1 == std::string_view::npos || s2 == s1) return p;
    const std::string_view version = line.substr(s2 + 1);
    if (version != "HTTP/1.1" && version != "HTTP/1.0") return p;
    p.keep_alive = version == "HTTP/1.1";
    p.request.method = std::string(line.substr(0, s1));
    const std::string_view target = line.substr(s1 + 1, s2 - s1 - 1);
    p.request.path = std::string(target.substr(0, target.find('?')));
    while (eol != std::string_view::npos && eol + 2 < text.size()) {
        const std::size_t start = eol + 2;
        eol = text.find("\r\n", start);
        const std::string_view h = text.substr(start, eol - start);
        if (h.empty()) break;
        const std::size_t colon = h.find(':');
        if (colon == std::string_view::npos) return p;
        const std::string_view name = h.substr(0, colon), value = trim(h.substr(colon + 1));
        if (iequals(name, "Host"))
            p.request.host = std::string(value);
        else if (iequals(name, "Last-Event-ID"))
            p.request.last_event_id = std::string(value);
        else if (iequals(name, "Connection"))
            p.keep_alive = iequals(value, "close")        ? false
                           : iequals(value, "keep-alive") ? true
                                                          : p.keep_alive;
        else if (iequals(name, "Content-Length"))
            p.has_body = p.has_body || value != "0";
        else if (iequals(name, "Transfer-Encoding"))
            p.has_body = true;
    }
    p.valid = true;
    return p;
}

/** A listening, non-blocking socket on host:port; -1 and `why` when none could be made. */
int listen_on(const std::string& host, int port, std::string& why) {
    addrinfo hints{};
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
    addrinfo* found = nullptr;
    const std::string service = std::to_string(port);
    if (const int e = ::getaddrinfo(host.c_str(), service.c_str(), &hints, &found); e != 0) {
        why = ::gai_strerror(e);
        return -1;
    }
    int fd = -1;
    for (addrinfo* a = found; a && fd < 0; a = a->ai_next) {
        fd = ::socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a->ai_protocol);
        if (fd < 0) continue;
        // SO_REUSEADDR only (a restart may reuse a port in TIME_WAIT); SO_REUSEPORT would let a
        // second server take a port already in use.
        int yes = 1;
        ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
        if (::bind(fd, a->ai_addr, a->ai_addrlen) != 0 || ::listen(fd, SOMAXCONN) != 0) {
            why = std::strerror(errno);
            ::close(fd);
            fd = -1;
        }
    }
    ::freeaddrinfo(found);
    return fd;
}

/** The port `fd` is bound to. */
int bound_port(int fd) {
    sockaddr_storage a{};
    socklen_t n = sizeof(a);
    if (::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &n) != 0) return 0;
    if (a.ss_family == AF_INET6) return ntohs(reinterpret_cast<sockaddr_in6*>(&a)->sin6_port);
    return ntohs(reinterpret_cast<sockaddr_in*>(&a)->sin_port);
}

double seconds(Clock::duration d) {
    return std::chrono::duration<double>(d).count();
}

}  // namespace

HttpLoop::HttpLoop(const std::string& host, int port, const Limits& limits) : limits_(limits) {
    std::string why;
    listen_fd_ = listen_on(host, port, why);
    if (listen_fd_ < 0)
        throw_error("--serve: cannot listen on {}:{} ({})", host, port,
                    why.empty() ? "not an address of this machine" : why);
    port_ = bound_port(listen_fd_);
    wake_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    if (wake_fd_ < 0) {
        ::close(listen_fd_);
        throw_error("--serve: cannot make an eventfd ({})", std::strerror(errno));
    }
}

HttpLoop::~HttpLoop() {
    stopping_ = true;
    notify();
    if (thread_.joinable()) thread_.join();
    ::close(wake_fd_);
    ::close(listen_fd_);
}

void HttpLoop::start(Route route, Pump pump, Note note) {
    route_ = std::move(route);
    pump_ = std::move(pump);
    note_ = std::move(note);
    thread_ = std::thread([this] { run(); });
}

void HttpLoop::notify() {
    news_ = true;
    const uint64_t one = 1;
    // A full counter (never in practice) already wakes the loop: the result does not matter.
    [[maybe_unused]] const ssize_t n = ::write(wake_fd_, &one, sizeof(one));
}

HttpLoopCounts HttpLoop::counts() const {
    return {refused_.load(), dropped_.load()};
}

void HttpLoop::note_once(std::atomic<bool>& said, const std::string& line) {
    if (note_ && !said.exchange(true)) note_(line);
}

void HttpLoop::run() {
    std::vector<std::unique_ptr<Connection>> conns;
    std::vector<pollfd> fds;
    auto last_sweep = Clock::now();
    while (!stopping_) {
        fds.clear();
        fds.push_back({wake_fd_, POLLIN, 0});
        fds.push_back({listen_fd_, POLLIN, 0});
        for (const auto& c : conns) {
            // Past a request's worth of unanswered input, reading waits for the answers to go.
            const bool read = c->stream || c->in.size() <= limits_.max_request_bytes;
            fds.push_back({c->fd,
                           static_cast<short>((read ? POLLIN : 0) | (c->queued > 0 ? POLLOUT : 0)),
                           0});
        }
        // Bounds are checked a few times a second; news and requests wake the loop at once.
        if (::poll(fds.data(), fds.size(), 250) < 0 && errno != EINTR) break;
        if (stopping_) break;
        const auto now = Clock::now();
        if (fds[0].revents & POLLIN) {
            uint64_t n = 0;
            [[maybe_unused]] const ssize_t r = ::read(wake_fd_, &n, sizeof(n));
        }
        // Connections accepted below come after the polled ones: only those have revents.
        const std::size_t polled = conns.size();
        for (std::size_t i = 0; i < polled; ++i) {
            Connection& c = *conns[i];
            const short ev = fds[i + 2].revents;
            bool keep = true;
            if (ev & (POLLIN | POLLHUP | POLLERR)) keep = on_readable(c);
            if (keep && (ev & POLLOUT)) keep = on_writable(c);
            if (!keep) {
                ::close(c.fd);
                c.fd = -1;
            }
        }
        if (fds[1].revents & POLLIN) accept_all(conns);
        if (news_.exchange(false)) pump_streams(conns);
        if (seconds(now - last_sweep) >= 0.25) {
            last_sweep = now;
            for (auto& c : conns)
                if (c->fd >= 0 && !within_bounds(*c, now)) {
                    ::close(c->fd);
                    c->fd = -1;
                }
        }
        // Send what the pumps and answers queued right away, rather than after the next poll.
        for (auto& c : conns)
            if (c->fd >= 0 && c->queued > 0 && !on_writable(*c)) {
                ::close(c->fd);
                c->fd = -1;
            }
        const auto closed = std::remove_if(conns.begin(), conns.end(), [&](const auto& c) {
            if (c->fd >= 0) return false;
            if (c->stream) --streams_;
            return true;
        });
        conns.erase(closed, conns.end());
    }
}

void HttpLoop::accept_all(std::vector<std::unique_ptr<Connection>>& conns) {
    for (;;) {
        const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0) return;  // EAGAIN: none left (or a transient error: the next poll retries)
        const auto now = Clock::now();
        std::size_t open = 0;
        for (const auto& c : conns) open += c->fd >= 0 ? 1 : 0;
        if (open >= limits_.max_connections) {
            // Make room by closing the connection idle the longest (a browser keeps some open
            // in case); when every one is busy, the newcomer is told why and closed.
            Connection* oldest = nullptr;
            for (auto& c : conns)
                if (c->fd >= 0 && c->idle() && (!oldest || c->active < oldest->active))
                    oldest = c.get();
            if (oldest) {
                ::close(oldest->fd);
                oldest->fd = -1;
            } else {
                ++refused_;
                const HttpReply r = text_reply(
                    503,
                    fmt::format("the live preview serves at most {} connections at once; close "
                                "a page or try again later\n",
                                limits_.max_connections),
                    "Retry-After: 5\r\n");
                const std::string text = head(r, r.body->size(), false) + *r.body;
                // Best effort, never blocking: a client that cannot take this loses it.
                [[maybe_unused]] const ssize_t n =
                    ::send(fd, text.data(), text.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
                ::close(fd);
                note_once(said_refused_,
                          fmt::format("live preview: more than {} connections at once; further "
                                      "ones are refused (503) until some close",
                                      limits_.max_connections));
                continue;
            }
        }
        int yes = 1;  // event lines are small and should go out at once
        ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &yes, sizeof(yes));
        auto c = std::make_unique<Connection>();
        c->fd = fd;
        c->moved = c->active = c->request_start = now;
        conns.push_back(std::move(c));
    }
}

bool HttpLoop::on_readable(Connection& c) {
    char buf[8192];
    while (c.stream || c.in.size() <= limits_.max_request_bytes) {
        const ssize_t n = ::recv(c.fd, buf, sizeof(buf), 0);
        if (n == 0) return false;  // the client closed
        if (n < 0) {
            if (errno == EINTR) continue;
            if (errno == EAGAIN || errno == EWOULDBLOCK) break;
            return false;
        }
        const auto now = Clock::now();
        if (c.stream) continue;  // a stream's client has nothing more to say
        if (c.in.empty()) c.request_start = now;
        c.active = now;
        c.in.append(buf, static_cast<std::size_t>(n));
    }
    return answer_requests(c);
}

bool HttpLoop::answer_requests(Connection& c) {
    // One answer at a time: a client that pipelines requests without reading holds its own
    // answers back and is dropped when they stall.
    while (!c.stream && !c.close_when_sent && c.queued == 0 && !c.in.empty()) {
        const auto now = Clock::now();
        const std::size_t end = c.in.find("\r\n\r\n");
        if (end == std::string::npos) {
            if (c.in.size() <= limits_.max_request_bytes) return true;  // more to come
            const HttpReply r = text_reply(431, "request headers too large\n");
            c.send(shared(head(r, r.body->size(), false) + *r.body), now);
            c.close_when_sent = true;
            return true;
        }
        const ParsedHead p = parse_head(std::string_view(c.in).substr(0, end + 2));
        c.in.erase(0, end + 4);
        c.request_start = now;
        HttpReply r;
        bool keep_alive = p.keep_alive;
        if (!p.valid || p.has_body) {
            r = text_reply(
                400, p.valid ? "request bodies are not accepted here\n" : "malformed request\n");
            keep_alive = false;
        } else if (p.request.method != "GET" && p.request.method != "HEAD") {
            r = text_reply(405, "only GET and HEAD are served here\n", "Allow: GET, HEAD\r\n");
        } else {
            r = route_(p.request);
        }
        if (r.event_stream && streams_ >= limits_.max_streams) {
            ++refused_;
            note_once(said_refused_,
                      fmt::format("live preview: more than {} open event streams; further ones "
                                  "are refused (503) until some close",
                                  limits_.max_streams));
            r = text_reply(503,
                           fmt::format("the live preview feeds at most {} open pages at once; "
                                       "close a page or try again later\n",
                                       limits_.max_streams),
                           "Retry-After: 5\r\n");
        }
        const bool head_only = p.request.method == "HEAD";
        if (r.event_stream) {
            // No length: the stream is the rest of the connection.
            c.send(shared(fmt::format("HTTP/1.1 200 OK\r\nContent-Type: text/event-stream\r\n"
                                      "Cache-Control: no-store\r\nConnection: close\r\n{}\r\n",
                                      r.headers)),
                   now);
            if (head_only) {
                c.close_when_sent = true;
                return true;
            }
            c.send(r.body, now);
            c.stream = true;
            c.cursor = r.cursor;
            c.in.clear();
            ++streams_;
            return true;
        }
        const std::size_t length = r.body ? r.body->size() : 0;
        c.send(shared(head(r, length, keep_alive)), now);
        if (!head_only) c.send(r.body, now);
        c.close_when_sent = !keep_alive;
    }
    return true;
}

bool HttpLoop::on_writable(Connection& c) {
    while (c.queued > 0) {
        iovec iov[16];
        int n = 0;
        std::size_t skip = c.front_sent;
        for (const auto& chunk : c.out) {
            if (n == 16) break;
            iov[n].iov_base = const_cast<char*>(chunk->data() + skip);
            iov[n].iov_len = chunk->size() - skip;
            skip = 0;
            ++n;
        }
        msghdr msg{};
        msg.msg_iov = iov;
        msg.msg_iovlen = static_cast<std::size_t>(n);
        const ssize_t sent = ::sendmsg(c.fd, &msg, MSG_NOSIGNAL | MSG_DONTWAIT);
        if (sent < 0) {
            if (errno == EINTR) continue;
            return errno == EAGAIN || errno == EWOULDBLOCK;
        }
        const auto now = Clock::now();
        c.moved = now;
        auto left = static_cast<std::size_t>(sent);
        c.queued -= left;
        while (left > 0) {
            const std::size_t rest = c.out.front()->size() - c.front_sent;
            if (left < rest) {
                c.front_sent += left;
                break;
            }
            left -= rest;
            c.out.pop_front();
            c.front_sent = 0;
        }
    }
    if (c.close_when_sent) return false;
    c.active = Clock::now();
    // The answer is out: a request that came behind it can be answered now.
    return answer_requests(c);
}

void HttpLoop::pump_streams(std::vector<std::unique_ptr<Connection>>& conns) {
    std::vector<StreamNews> news;
    std::vector<Connection*> streams;
    for (auto& c : conns)
        if (c->fd >= 0 && c->stream) {
            news.push_back({c->cursor, nullptr});
            streams.push_back(c.get());
        }
    if (streams.empty()) return;
    pump_(news);
    const auto now = Clock::now();
    for (std::size_t i = 0; i < streams.size(); ++i) {
        streams[i]->cursor = news[i].cursor;
        streams[i]->send(std::move(news[i].text), now);
    }
}

bool HttpLoop::within_bounds(Connection& c, Clock::time_point now) {
    const bool stalled = c.queued > 0 && seconds(now - c.moved) > limits_.stall_seconds;
    const bool backlog = c.stream && c.queued > limits_.max_stream_backlog;
    if (stalled || backlog) {
        ++dropped_;
        note_once(
            said_dropped_,
            fmt::format(
                "live preview: dropped a client that stopped reading ({}); the "
                "render does not wait for clients",
                stalled ? fmt::format("nothing taken for {:g} s", limits_.stall_seconds)
                        : fmt::format("over {} KiB waiting", limits_.max_stream_backlog >> 10)));
        return false;
    }
    if (c.stream) {
        static const auto beat = shared(": still here\n\n");
        if (c.queued == 0 && seconds(now - c.moved) > limits_.heartbeat_seconds) c.send(beat, now);
        return true;
    }
    if (!c.in.empty() && c.queued == 0 && seconds(now - c.request_start) > limits_.request_seconds)
        return false;  // a request that never completes
    return !(c.idle() && seconds(now - c.active) > limits_.idle_seconds);
}

}  // namespace spangle
