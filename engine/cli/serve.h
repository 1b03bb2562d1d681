#pragma once
// The live preview page of `spangle render --serve [ADDR:]PORT`: a small web page that shows the
// latest pass through the OCIO display and view, the pass and samples reached, progress, and the
// reload lines and errors as they come (server-sent events). The render never waits for it: a
// pass is handed over as a copy and encoded to PNG on the server's own thread, the newest pass
// replacing one not yet encoded. It serves three fixed routes and no files; it binds to
// 127.0.0.1 unless told otherwise, and then answers only requests addressed to the loopback host.

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
    struct Event {
        uint64_t id;
        std::string type, data;  // SSE event name and JSON payload
    };
    void push_event(const std::string& type, const std::string& data);
    void encode_loop();

    std::string url_;
    std::string host_;  // bound address
    int port_ = 0;
    bool loopback_ = true;

    std::mutex mutex_;
    std::condition_variable changed_;  // events, progress or a pass to encode
    bool stopping_ = false;
    std::deque<Event> events_;  // the latest events, for clients that connect late
    uint64_t next_event_ = 1;
    uint64_t done_ = 0, total_ = 0, progress_version_ = 0;
    std::chrono::steady_clock::time_point progress_at_;
    // The pass waiting to be encoded, and the latest encoded one.
    struct Pending {
        std::vector<float> image;
        uint32_t width = 0, height = 0, spp = 0, target = 0, block = 1;
        const ColorConfig* color = nullptr;
    };
    std::unique_ptr<Pending> pending_;
    std::string png_;
    uint64_t image_version_ = 0;

    struct Http;
    std::unique_ptr<Http> http_;
    std::thread listener_, encoder_;
};

}  // namespace spangle
