#pragma once
// A small HTTP/1.1 server on one thread of its own, for the live preview page (preview_server.h):
// every socket is non-blocking and served by one poll() loop, so an open event stream
// (server-sent events) costs a few hundred bytes and no thread, and any number of viewers leave
// the page and its image answering. It answers GET and HEAD only, reads no request bodies, and
// keeps connections alive between requests.
//
// Bounds, each with its reason:
// - at most Limits::max_connections sockets at once (file descriptors and memory are finite):
//   beyond that a new connection is answered "503 Service Unavailable" and closed, after closing
//   the longest idle kept-alive connection when there is one instead;
// - at most Limits::max_streams event streams; a further /events gets a 503 that says so;
// - a client that stops reading is dropped: when what waits to be sent to it has not moved for
//   Limits::stall_seconds, or when an event stream's unsent backlog passes
//   Limits::max_stream_backlog bytes. Nothing is ever written with a blocking call, so a stalled
//   client costs its own backlog and nothing else;
// - a request whose headers are not complete within Limits::request_seconds, or larger than
//   Limits::max_request_bytes, is dropped; an idle kept-alive connection is closed after
//   Limits::idle_seconds.

#include <array>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <thread>
#include <vector>

namespace spangle {

/** The parts of a request the preview page reads. */
struct HttpRequest {
    std::string method;         ///< "GET" or "HEAD" (others are answered 405 by the loop)
    std::string path;           ///< the target without its query ("/image.png")
    std::string host;           ///< the Host header; empty: none
    std::string last_event_id;  ///< the Last-Event-ID header of a reconnecting event stream
};

/** Where an event stream stands, kept by the loop for its owner (ids and versions it has sent). */
using StreamCursor = std::array<uint64_t, 3>;

/** The answer to a request: a whole body, or the start of an event stream. */
struct HttpReply {
    int status = 200;                         ///< HTTP status code
    std::string content_type = "text/plain";  ///< of the body
    std::shared_ptr<const std::string> body;  ///< null: empty; shared, never copied per client
    std::string headers;                      ///< extra header lines, each ending in "\r\n"
    bool event_stream = false;                ///< body is the stream's first text; more follows
    StreamCursor cursor{};                    ///< an event stream's position after `body`
};

/** Counters of what the loop did, for messages and tests. */
struct HttpLoopCounts {
    uint64_t refused = 0;  ///< connections or streams answered 503 at a cap
    uint64_t dropped = 0;  ///< clients dropped for not reading
};

/** The server loop and its thread. Route and pump run on the loop's thread, one at a time. */
class HttpLoop {
public:
    /** The bounds of the header comment. */
    struct Limits {
        std::size_t max_connections = 256;           ///< open sockets at once
        std::size_t max_streams = 192;               ///< open event streams at once
        std::size_t max_stream_backlog = 256 << 10;  ///< unsent bytes of one stream
        std::size_t max_request_bytes = 16 << 10;    ///< request line and headers
        double stall_seconds = 10.0;      ///< unsent output not moving this long: dropped
        double request_seconds = 10.0;    ///< to send a request's headers
        double idle_seconds = 60.0;       ///< a kept-alive connection waiting for a request
        double heartbeat_seconds = 15.0;  ///< a comment on a quiet stream (finds closed ones)
    };
    /** Answers one request (the loop adds the status line, length and connection headers). */
    using Route = std::function<HttpReply(const HttpRequest&)>;
    /** One event stream's news: `cursor` is where it stands, to be moved on; `text` receives
     *  what to send (null: nothing). */
    struct StreamNews {
        StreamCursor cursor;
        std::shared_ptr<const std::string> text;
    };
    /** Fills in the news of every open stream at once (after notify()). */
    using Pump = std::function<void(std::span<StreamNews>)>;
    /** Called with a line worth telling the user (the first refusal, the first drop). */
    using Note = std::function<void(const std::string&)>;

    /** Listens on `host`:`port` (0: a free port). Throws SpangleError when it cannot. */
    HttpLoop(const std::string& host, int port, const Limits& limits);
    /** Stops the thread and closes every connection. */
    ~HttpLoop();
    HttpLoop(const HttpLoop&) = delete;
    HttpLoop& operator=(const HttpLoop&) = delete;

    /** The port listened on. */
    int port() const { return port_; }
    /** Starts serving on a thread of its own. */
    void start(Route route, Pump pump, Note note);
    /** There is news for the event streams: the loop pumps them. Thread-safe, never blocks. */
    void notify();
    /** What the loop refused and dropped so far. Thread-safe. */
    HttpLoopCounts counts() const;

private:
    struct Connection;
    /** The loop's body, until the destructor. */
    void run();
    /** Accepts every pending connection. */
    void accept_all(std::vector<std::unique_ptr<Connection>>& conns);
    /** Reads what `c` sent and answers complete requests; false: close it. */
    bool on_readable(Connection& c);
    /** Answers the complete requests at the start of c's input while nothing waits to be sent. */
    bool answer_requests(Connection& c);
    /** Sends what `c` has waiting; false: close it. */
    bool on_writable(Connection& c);
    /** Appends every stream's news (notify()) and heartbeats. */
    void pump_streams(std::vector<std::unique_ptr<Connection>>& conns);
    /** False when `c` broke a bound (stalled, too slow, too long idle): close it. */
    bool within_bounds(Connection& c, std::chrono::steady_clock::time_point now);
    /** Tells the user `line` once per kind (`said` remembers). */
    void note_once(std::atomic<bool>& said, const std::string& line);

    Limits limits_;                      ///< bounds
    int listen_fd_ = -1;                 ///< the listening socket
    int wake_fd_ = -1;                   ///< an eventfd: news, or stop
    int port_ = 0;                       ///< bound port
    std::size_t streams_ = 0;            ///< open event streams (the loop's thread only)
    Route route_;                        ///< answers requests
    Pump pump_;                          ///< news for the streams
    Note note_;                          ///< lines for the user
    std::atomic<bool> stopping_{false};  ///< the destructor has begun
    std::atomic<bool> news_{false};      ///< notify() since the last pump
    std::atomic<uint64_t> refused_{0}, dropped_{0};                ///< HttpLoopCounts
    std::atomic<bool> said_refused_{false}, said_dropped_{false};  ///< noted once
    std::thread thread_;                                           ///< runs run()
};

}  // namespace spangle
