#pragma once
// The live preview page of `spangle render --serve [ADDR:]PORT`: a small web page that shows the
// latest pass through the OCIO display and view, what the renderer is doing (loading, building
// BVHs, making materials, the pass and samples reached), progress, and the reload lines and
// errors as they come (server-sent events). The render never waits for it: a pass is handed over
// as a copy and encoded to PNG on the server's own thread, the newest pass replacing one not yet
// encoded. It serves three fixed routes and no files through a single-threaded non-blocking loop
// (http_loop.h: any number of open pages up to its caps, slow clients dropped); it binds to
// 127.0.0.1 unless told otherwise, and then answers only requests addressed to the loopback host.
//
// It lives beside the render modes rather than in watch/: a one-shot render serves it too
// (`render --serve` shows the passes and progress of a still), while watch mode adds the reload
// lines and errors to its log.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "cli/http_loop.h"
#include "core/progress.h"

namespace spangle {

class ColorConfig;
struct Logger;

/** Splits "PORT" or "ADDR:PORT" ("[::1]:PORT" for IPv6) into address (default 127.0.0.1) and
 *  port. Throws SpangleError when malformed. */
std::pair<std::string, int> parse_serve_address(const std::string& spec);

/** The live preview page: an HTTP loop and a PNG encoder, each on a thread of its own. */
class PreviewServer {
public:
    /** Binds `spec` ("PORT" or "ADDR:PORT"; port 0 picks a free one) and starts serving.
     *  `note` receives lines for the user (a client dropped, connections refused); may be
     *  empty. Throws SpangleError when the spec is malformed or the address cannot be bound. */
    explicit PreviewServer(const std::string& spec,
                           std::function<void(const std::string&)> note = {},
                           const HttpLoop::Limits& limits = {});
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
    /** What the renderer is doing now ("loading scene.toml", "building BVHs"), `fraction` of it
     *  done in [0, 1] or < 0 when unknown: the page's status line until the next pass. A
     *  WorkProgress can forward here. Thread-safe; at most a few updates a second go out. */
    void stage(const std::string& what, double fraction = -1.0);
    /** A line for the page's log: level "info" (reloads) or "error". */
    void log(const std::string& level, const std::string& text);

private:
    /** One server-sent event, kept for clients that connect late. */
    struct Event {
        uint64_t id;       ///< the SSE id (Last-Event-ID of a reconnecting client)
        std::string text;  ///< the whole event as sent ("id: ..\nevent: ..\ndata: ..\n\n")
    };
    /** Answers /, /image.png and /events, and refuses foreign Host headers. */
    HttpReply route(const HttpRequest& req);
    /** The number of the event after which a client that last heard `last_event_id` resumes
     *  (0: every kept event). Under mutex_. */
    uint64_t event_after(const std::string& last_event_id) const;
    /** What a stream at `cursor` has not heard yet, moving the cursor on; the caller holds
     *  mutex_. Cursor: last event number, progress version, status version. */
    std::string news_for(StreamCursor& cursor) const;
    /** Every open stream's news (HttpLoop::Pump). */
    void pump(std::span<HttpLoop::StreamNews> news);
    /** Keeps the latest events (kKeptEvents); the caller holds mutex_. */
    void push_event(const std::string& type, const std::string& data);
    /** Sets the status line; the caller holds mutex_. */
    void set_status(const std::string& text, double fraction);
    /** The encoder thread: turns the newest pending pass into the PNG the page shows. */
    void encode_loop();

    /** A pass handed over by the render, waiting to be encoded. */
    struct Pending {
        std::vector<float> image;                                        ///< working space
        uint32_t width = 0, height = 0, spp = 0, target = 0, block = 1;  ///< as publish_pass
        const ColorConfig* color = nullptr;                              ///< outlives the server
        uint64_t stage_serial = 0;  ///< stage_serial_ when published
    };

    std::string url_;       ///< the page's address
    std::string host_;      ///< bound address
    bool loopback_ = true;  ///< bound to loopback: answer loopback Host headers only

    mutable std::mutex mutex_;         ///< guards everything below but the loop and threads
    std::condition_variable changed_;  ///< a pass to encode, or stopping
    bool stopping_ = false;            ///< the destructor has begun
    std::deque<Event> events_;         ///< the latest events, for clients that connect late
    uint64_t next_event_ = 1;          ///< number of the next event
    /** Event ids are "TAG.N", TAG this server's own (its start time and process): a browser
     *  that reconnects to a new server on the same port sends the id it last heard from the old
     *  one, which the new one does not know: it hears every kept event (a bare number from the
     *  old server was taken as a place in the new one's events, and the page missed every pass
     *  and log line until the new server's count passed it). */
    std::string event_tag_;
    uint64_t done_ = 0, total_ = 0;                      ///< samples of the current render
    uint64_t progress_version_ = 0;                      ///< bumped on each progress update sent
    std::chrono::steady_clock::time_point progress_at_;  ///< when progress was last sent
    std::string status_ = "starting";                    ///< the page's status line
    double status_fraction_ = -1.0;                      ///< of the stage in status_; < 0: none
    uint64_t status_version_ = 1;                        ///< bumped with each status sent
    std::chrono::steady_clock::time_point status_at_;    ///< when the status was last sent
    std::string stage_;                                  ///< the last stage() text
    uint64_t stage_serial_ = 0;                          ///< bumped when stage() names new work
    std::unique_ptr<Pending> pending_;        ///< the pass waiting to be encoded; null: none
    std::shared_ptr<const std::string> png_;  ///< the latest encoded pass; null: none yet
    uint64_t image_version_ = 0;              ///< bumped with each encoded pass

    std::unique_ptr<HttpLoop> http_;  ///< the server loop (its thread)
    std::thread encoder_;             ///< encoding passes
};

/** The page --serve asks for (`spec`: [ADDR:]PORT; empty: none, nullptr). Prints its address on
 *  stdout, even with --quiet: it was asked for; lines about clients go to `log`. Throws
 *  SpangleError when it cannot listen. */
std::unique_ptr<PreviewServer> start_preview_server(const std::string& spec, const Logger& log);

/** A WorkProgress that tells `server` (when not null) and then `inner` (when set). */
WorkProgress work_progress_to(PreviewServer* server, WorkProgress inner);

}  // namespace spangle
