// The live preview page: see preview_server.h.

#include "cli/preview_server.h"

#include <fmt/format.h>
#include <httplib.h>
#include <sys/socket.h>

#include <chrono>
#include <cstdio>

#include "color/color_config.h"
#include "color/image_output.h"
#include "core/error.h"
#include "render/render_options.h"

namespace spangle {
namespace {

constexpr std::size_t kKeptEvents = 200;  ///< events a late client still gets

/** The page: an image, a status line and the log, fed by /events. */
constexpr const char* kPage = R"HTML(<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>Spangle live preview</title>
<style>
body { margin: 0; background: #1e1e1e; color: #ddd; font: 14px/1.4 sans-serif; }
header { padding: 8px 12px; background: #2a2a2a; display: flex; gap: 16px; align-items: center; }
#bar { flex: 1; height: 6px; background: #444; border-radius: 3px; overflow: hidden; }
#fill { height: 100%; width: 0; background: #d9a520; }
main { padding: 12px; text-align: center; }
img { max-width: 100%; image-rendering: auto; box-shadow: 0 0 12px #000; }
pre { margin: 0 12px 12px; padding: 8px; background: #111; max-height: 30vh; overflow: auto;
      text-align: left; white-space: pre-wrap; }
.error { color: #f66; }
</style></head>
<body>
<header><strong>Spangle</strong><span id="status">waiting for the first pass</span>
<div id="bar"><div id="fill"></div></div><span id="conn">connecting</span></header>
<main><img id="image" alt="latest pass"></main>
<pre id="log"></pre>
<script>
const $ = (id) => document.getElementById(id);
const es = new EventSource('/events');
es.onopen = () => { $('conn').textContent = 'live'; };
es.onerror = () => { $('conn').textContent = 'disconnected'; };
es.addEventListener('pass', (e) => {
  const d = JSON.parse(e.data);
  $('image').src = '/image.png?v=' + d.image;
  $('status').textContent = d.spp === 0
    ? 'preview pass (1/' + d.block + ' resolution) of ' + d.target + ' spp'
    : 'pass ' + d.pass + ': ' + d.spp + ' of ' + d.target + ' spp';
});
es.addEventListener('progress', (e) => {
  const d = JSON.parse(e.data);
  $('fill').style.width = (d.total > 0 ? 100 * d.done / d.total : 0) + '%';
});
es.addEventListener('log', (e) => {
  const d = JSON.parse(e.data);
  const line = document.createElement('div');
  line.className = d.level;
  line.textContent = d.text;
  $('log').appendChild(line);
  $('log').scrollTop = $('log').scrollHeight;
});
</script></body></html>
)HTML";

/** `s` as a JSON string literal, quotes included. */
std::string json_string(const std::string& s) {
    std::string out = "\"";
    for (const char ch : s) {
        const auto c = static_cast<unsigned char>(ch);
        if (c == '"' || c == '\\')
            out += {'\\', ch};
        else if (c == '\n')
            out += "\\n";
        else if (c < 0x20)
            out += fmt::format("\\u{:04x}", c);
        else
            out += ch;
    }
    return out + "\"";
}

/** The host part of a Host header ("127.0.0.1:8080" -> "127.0.0.1", "[::1]:80" -> "[::1]"). */
std::string host_name(const std::string& header) {
    if (!header.empty() && header[0] == '[') return header.substr(0, header.find(']') + 1);
    return header.substr(0, header.find(':'));
}

}  // namespace

std::pair<std::string, int> parse_serve_address(const std::string& spec) {
    // The port follows the last colon.
    const auto colon = spec.rfind(':');
    std::string host = colon == std::string::npos ? "127.0.0.1" : spec.substr(0, colon);
    const std::string port_text = colon == std::string::npos ? spec : spec.substr(colon + 1);
    if (host.size() > 2 && host.front() == '[' && host.back() == ']')
        host = host.substr(1, host.size() - 2);
    unsigned port = 0;
    char tail = 0;
    if (host.empty() || port_text.empty() || port_text[0] < '0' || port_text[0] > '9' ||
        std::sscanf(port_text.c_str(), "%u%c", &port, &tail) != 1 || port > 65535)
        throw_error("--serve expects PORT or ADDR:PORT with a port in 0..65535, got '{}'", spec);
    return {host, static_cast<int>(port)};
}

struct PreviewServer::Http {
    httplib::Server server;
};

PreviewServer::PreviewServer(const std::string& spec) : http_(std::make_unique<Http>()) {
    std::tie(host_, port_) = parse_serve_address(spec);
    loopback_ = host_ == "127.0.0.1" || host_ == "localhost" || host_ == "::1";
    // The library's default also sets SO_REUSEPORT, which lets a second server take a port
    // already in use: only SO_REUSEADDR here (a restart may reuse a port in TIME_WAIT).
    http_->server.set_socket_options([](int sock) {
        int yes = 1;
        ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
    });
    add_routes();
    const int port = port_;
    httplib::Server& s = http_->server;
    const bool bound =
        port_ == 0 ? (port_ = s.bind_to_any_port(host_)) > 0 : s.bind_to_port(host_, port_);
    if (!bound)
        throw_error("--serve: cannot listen on {}:{} (in use, or not an address of this machine)",
                    host_, port);
    const bool v6 = host_.find(':') != std::string::npos;
    url_ = fmt::format("http://{}{}{}:{}/", v6 ? "[" : "", host_, v6 ? "]" : "", port_);
    listener_ = std::thread([this] { http_->server.listen_after_bind(); });
    encoder_ = std::thread([this] { encode_loop(); });
}

void PreviewServer::add_routes() {
    httplib::Server& s = http_->server;
    // Bound to loopback, answer only requests addressed to it: a page elsewhere cannot reach
    // this one through a rebound DNS name.
    s.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
        if (!loopback_) return httplib::Server::HandlerResponse::Unhandled;
        const std::string h = host_name(req.get_header_value("Host"));
        if (h == "127.0.0.1" || h == "localhost" || h == "[::1]")
            return httplib::Server::HandlerResponse::Unhandled;
        res.status = 403;
        res.set_content("forbidden: not a loopback host\n", "text/plain");
        return httplib::Server::HandlerResponse::Handled;
    });
    s.Get("/", [](const httplib::Request&, httplib::Response& res) {
        res.set_header("Cache-Control", "no-store");
        res.set_content(kPage, "text/html; charset=utf-8");
    });
    s.Get("/image.png", [this](const httplib::Request&, httplib::Response& res) {
        std::string png;
        {
            std::lock_guard<std::mutex> lock(mutex_);
            png = png_;
        }
        res.set_header("Cache-Control", "no-store");
        if (png.empty()) {
            res.status = 503;
            res.set_content("no pass yet\n", "text/plain");
            return;
        }
        res.set_content(png, "image/png");
    });
    s.Get("/events", [this](const httplib::Request& req, httplib::Response& res) {
        res.set_header("Cache-Control", "no-store");
        // Every kept event after the client's last one, then new ones as they come.
        auto last = std::make_shared<uint64_t>(0);
        if (req.has_header("Last-Event-ID"))
            *last = std::strtoull(req.get_header_value("Last-Event-ID").c_str(), nullptr, 10);
        auto progress_seen = std::make_shared<uint64_t>(0);
        res.set_chunked_content_provider(
            "text/event-stream", [this, last, progress_seen](std::size_t, httplib::DataSink& sink) {
                std::string out;
                if (!next_events(*last, *progress_seen, out)) return false;
                return sink.write(out.data(), out.size());
            });
    });
}

bool PreviewServer::next_events(uint64_t& last, uint64_t& progress_seen, std::string& out) {
    std::unique_lock<std::mutex> lock(mutex_);
    const auto fresh = [&] {
        return stopping_ || progress_version_ != progress_seen ||
               (!events_.empty() && events_.back().id > last);
    };
    if (!changed_.wait_for(lock, std::chrono::seconds(1), fresh))
        out = ": still here\n\n";  // finds closed connections
    if (stopping_) return false;
    for (const Event& e : events_)
        if (e.id > last) {
            out += fmt::format("id: {}\nevent: {}\ndata: {}\n\n", e.id, e.type, e.data);
            last = e.id;
        }
    if (progress_version_ != progress_seen) {
        out +=
            fmt::format("event: progress\ndata: {{\"done\":{},\"total\":{}}}\n\n", done_, total_);
        progress_seen = progress_version_;
    }
    return true;
}

PreviewServer::~PreviewServer() {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        stopping_ = true;
    }
    changed_.notify_all();
    http_->server.stop();
    if (listener_.joinable()) listener_.join();
    if (encoder_.joinable()) encoder_.join();
}

void PreviewServer::push_event(const std::string& type, const std::string& data) {
    events_.push_back({next_event_++, type, data});
    if (events_.size() > kKeptEvents) events_.pop_front();
}

void PreviewServer::publish_pass(const std::vector<float>& image, uint32_t width, uint32_t height,
                                 uint32_t spp, uint32_t target, uint32_t block,
                                 const ColorConfig& color) {
    auto p = std::make_unique<Pending>();
    p->image = image;  // the render goes on with its own buffer
    p->width = width;
    p->height = height;
    p->spp = spp;
    p->target = target;
    p->block = block;
    p->color = &color;
    {
        std::lock_guard<std::mutex> lock(mutex_);
        pending_ = std::move(p);  // an older pass not yet encoded is dropped
    }
    changed_.notify_all();
}

void PreviewServer::progress(uint64_t done, uint64_t total) {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        if (done == done_ && total == total_) return;
        // At most a few updates a second (the render reports every wave of tiles).
        const auto now = std::chrono::steady_clock::now();
        if (done < total && done >= done_ && total == total_ &&
            now - progress_at_ < std::chrono::milliseconds(200))
            return;
        progress_at_ = now;
        done_ = done;
        total_ = total;
        ++progress_version_;
    }
    changed_.notify_all();
}

void PreviewServer::log(const std::string& level, const std::string& text) {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        push_event("log", fmt::format("{{\"level\":{},\"text\":{}}}", json_string(level),
                                      json_string(text)));
    }
    changed_.notify_all();
}

void PreviewServer::encode_loop() {
    for (;;) {
        std::unique_ptr<Pending> p;
        {
            std::unique_lock<std::mutex> lock(mutex_);
            changed_.wait(lock, [&] { return stopping_ || pending_ != nullptr; });
            if (stopping_) return;
            p = std::move(pending_);
        }
        std::string png;
        try {
            PngOptions o;
            o.block = p->block;
            o.compression_level = 1;
            png = encode_png_preview(p->image, static_cast<int>(p->width),
                                     static_cast<int>(p->height), *p->color, o);
        } catch (const SpangleError& e) {
            log("error", fmt::format("live preview: {}", e.what()));
            continue;
        }
        uint32_t passes = 0;  // passes ended, counting the preview as none
        for (const uint32_t end : pass_ends(p->target)) passes += end <= p->spp ? 1 : 0;
        {
            std::lock_guard<std::mutex> lock(mutex_);
            png_ = std::move(png);
            ++image_version_;
            push_event("pass", fmt::format("{{\"pass\":{},\"spp\":{},\"target\":{},\"block\":{},"
                                           "\"image\":{}}}",
                                           passes, p->spp, p->target, p->block, image_version_));
        }
        changed_.notify_all();
    }
}

std::unique_ptr<PreviewServer> start_preview_server(const std::string& spec) {
    if (spec.empty()) return nullptr;
    auto server = std::make_unique<PreviewServer>(spec);
    fmt::print("live preview at {}\n", server->url());  // even with --quiet: it was asked for
    std::fflush(stdout);
    return server;
}

}  // namespace spangle
