#pragma once
// The live preview page of `spangle render --serve [ADDR:]PORT`: a small web page that shows the
// latest pass through the OCIO display and view, the pass and samples reached, progress, and the
// reload lines and errors as they come (server-sent events). The render never waits for it: a
// pass is handed over as a copy and encoded to PNG on the server's own thread, the newest pass
// replacing one not yet encoded. It serves three fixed routes and no files; it binds to
// 127.0.0.1 unless told otherwise, and then answers only requests addressed to the loopback host.
//
// It lives beside the render modes rather than in watch/: a one-shot render serves it too
// (`render --serve` shows the passes and progress of a still), while watch mode adds the reload
// lines and errors to its log.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace spangle {

class ColorConfig;

/** Splits "PORT" or "ADDR:PORT" ("[::1]:PORT" for IPv6) into address (default 127.0.0.1) and
 *  port. Throws SpangleError when malformed. */
std::pair<std::string, int> parse_serve_address(const std::string& spec);

/** The live preview page: an HTTP server on two threads of its own (listening, encoding). */
class PreviewServer {
public:
    /** Binds `spec` ("PORT" or "ADDR:PORT"; port 0 picks a free one) and starts serving.
     *  Throws SpangleError when the spec is malformed or the address cannot be bound. */
    explicit PreviewServer(const std::string& spec);
    ~PreviewServer();
    PreviewServer(const PreviewServer&) = delete;
    PreviewServer& operator=(const PreviewServer&) = delete;

    /** The page's address, e.g. "http://127.0.0.1:8080/". */
    const std::string& url() const { return url_; }

    /** A pass ended: `image` (working space) after `spp` of `target` samples per pixel (0: a
     *  preview pass with blocks of `block` pixels). `color` must outlive the server. */
    void publish_pass(const std::vector<float>& image, uint32_t width, uint32_t height,
                      uint32_t spp, uint32_t target, uint32_t block, const ColorConfig& color);
    /** Samples done of the current render. */
    void progress(uint64_t done, uint64_t total);
    /** A line for the page's log: level "info" (reloads) or "error". */
    void log(const std::string& level, const std::string& text);

private:
    /** One server-sent event, kept for clients that connect late. */
    struct Event {
        uint64_t id;             ///< the SSE id (Last-Event-ID of a reconnecting client)
        std::string type, data;  ///< SSE event name and JSON payload
    };
    /** Registers the routes (/, /image.png, /events) and the loopback Host check. */
    void add_routes();
    /** Waits up to a second for news after event `last` and progress version `progress_seen`,
     *  appends them to `out` as SSE text and moves both on; false once the server stops. */
    bool next_events(uint64_t& last, uint64_t& progress_seen, std::string& out);
    /** Keeps the latest events (kKeptEvents); the caller holds mutex_. */
    void push_event(const std::string& type, const std::string& data);
    /** The encoder thread: turns the newest pending pass into the PNG the page shows. */
    void encode_loop();

    /** A pass handed over by the render, waiting to be encoded. */
    struct Pending {
        std::vector<float> image;                                        ///< working space
        uint32_t width = 0, height = 0, spp = 0, target = 0, block = 1;  ///< as publish_pass
        const ColorConfig* color = nullptr;                              ///< outlives the server
    };

    std::string url_;       ///< the page's address
    std::string host_;      ///< bound address
    int port_ = 0;          ///< bound port
    bool loopback_ = true;  ///< bound to loopback: answer loopback Host headers only

    std::mutex mutex_;                 ///< guards everything below but the threads
    std::condition_variable changed_;  ///< events, progress or a pass to encode
    bool stopping_ = false;            ///< the destructor has begun
    std::deque<Event> events_;         ///< the latest events, for clients that connect late
    uint64_t next_event_ = 1;          ///< id of the next event
    uint64_t done_ = 0, total_ = 0;    ///< samples of the current render
    uint64_t progress_version_ = 0;    ///< bumped on each progress update sent
    std::chrono::steady_clock::time_point progress_at_;  ///< when progress was last sent
    std::unique_ptr<Pending> pending_;  ///< the pass waiting to be encoded; null: none
    std::string png_;                   ///< the latest encoded pass
    uint64_t image_version_ = 0;        ///< bumped with each encoded pass

    struct Http;                      ///< the httplib server, kept out of this header
    std::unique_ptr<Http> http_;      ///< the server
    std::thread listener_, encoder_;  ///< serving requests; encoding passes
};

/** The page --serve asks for (`spec`: [ADDR:]PORT; empty: none, nullptr). Prints its address on
 *  stdout, even with --quiet: it was asked for. Throws SpangleError when it cannot listen. */
std::unique_ptr<PreviewServer> start_preview_server(const std::string& spec);

}  // namespace spangle
