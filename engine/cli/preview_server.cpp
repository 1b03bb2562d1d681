// The live preview page: see preview_server.h.

#include "cli/preview_server.h"

#include <fmt/format.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>

#include "color/color_config.h"
#include "color/image_output.h"
#include "core/error.h"
#include "core/hash.h"
#include "core/log.h"
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
<header><strong>Spangle</strong><span id="status">connecting</span>
<div id="bar"><div id="fill"></div></div><span id="conn">connecting</span></header>
<main><img id="image" alt="latest pass"></main>
<pre id="log"></pre>
<script>
const $ = (id) => document.getElementById(id);
const es = new EventSource('/events');
es.onopen = () => { $('conn').textContent = 'live'; };
es.onerror = () => { $('conn').textContent = 'disconnected'; };
es.addEventListener('pass', (e) => {
  $('image').src = '/image.png?v=' + JSON.parse(e.data).image;
});
es.addEventListener('status', (e) => {
  const d = JSON.parse(e.data);
  $('status').textContent = d.text + (d.fraction >= 0 ? ' ' + Math.floor(100 * d.fraction) + '%' : '');
  if (d.fraction >= 0) $('fill').style.width = 100 * d.fraction + '%';
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

namespace {

/** The status line of a pass. */
std::string pass_status(uint32_t passes, uint32_t spp, uint32_t target, uint32_t block) {
    if (spp == 0) return fmt::format("preview pass (1/{} resolution) of {} spp", block, target);
    return fmt::format("pass {}: {} of {} spp", passes, spp, target);
}

}  // namespace

PreviewServer::PreviewServer(const std::string& spec, std::function<void(const std::string&)> note,
                             const HttpLoop::Limits& limits) {
    int port = 0;
    std::tie(host_, port) = parse_serve_address(spec);
    loopback_ = host_ == "127.0.0.1" || host_ == "localhost" || host_ == "::1";
    http_ = std::make_unique<HttpLoop>(host_, port, limits);
    event_tag_ = fmt::format(
        "{:x}",
        hash2(static_cast<uint64_t>(std::chrono::system_clock::now().time_since_epoch().count()),
              static_cast<uint64_t>(::getpid())) &
            0xffffffffffull);
    const bool v6 = host_.find(':') != std::string::npos;
    url_ = fmt::format("http://{}{}{}:{}/", v6 ? "[" : "", host_, v6 ? "]" : "", http_->port());
    encoder_ = std::thread([this] { encode_loop(); });
    http_->start([this](const HttpRequest& req) { return route(req); },
                 [this](std::span<HttpLoop::StreamNews> news) { pump(news); }, std::move(note));
}

PreviewServer::~PreviewServer() {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        stopping_ = true;
    }
    changed_.notify_all();
    if (encoder_.joinable()) encoder_.join();  // it notifies the loop: stopped first
    http_.reset();                             // stops the loop before what its routes read goes
}

HttpReply PreviewServer::route(const HttpRequest& req) {
    static const auto page = std::make_shared<const std::string>(kPage);
    HttpReply r;
    // Bound to loopback, answer only requests addressed to it: a page elsewhere cannot reach
    // this one through a rebound DNS name.
    const std::string h = host_name(req.host);
    if (loopback_ && h != "127.0.0.1" && h != "localhost" && h != "[::1]") {
        r.status = 403;
        r.body = std::make_shared<const std::string>("forbidden: not a loopback host\n");
    } else if (req.path == "/") {
        r.content_type = "text/html; charset=utf-8";
        r.body = page;
    } else if (req.path == "/image.png") {
        std::lock_guard<std::mutex> lock(mutex_);
        if (png_) {
            r.content_type = "image/png";
            r.body = png_;  // shared: a thousand requests hold one copy
        } else {
            r.status = 503;
            r.body = std::make_shared<const std::string>("no pass yet\n");
        }
    } else if (req.path == "/events") {
        // Every kept event after the client's last one, then the current progress and status;
        // new ones follow as they come (pump).
        r.event_stream = true;
        std::lock_guard<std::mutex> lock(mutex_);
        r.cursor[0] = event_after(req.last_event_id);
        r.body = std::make_shared<const std::string>("retry: 2000\n\n" + news_for(r.cursor));
    } else {
        r.status = 404;
        r.body = std::make_shared<const std::string>("not found\n");
    }
    return r;
}

uint64_t PreviewServer::event_after(const std::string& last_event_id) const {
    // This server's own id, of an event it sent: resume after it. Anything else (none, another
    // server's, one from the future): from the first kept event.
    const std::string prefix = event_tag_ + ".";
    if (last_event_id.rfind(prefix, 0) != 0) return 0;
    const std::string n = last_event_id.substr(prefix.size());
    if (n.empty() || n.find_first_not_of("0123456789") != std::string::npos) return 0;
    const uint64_t id = std::strtoull(n.c_str(), nullptr, 10);
    return id < next_event_ ? id : 0;
}

std::string PreviewServer::news_for(StreamCursor& cursor) const {
    std::string out;
    for (const Event& e : events_)
        if (e.id > cursor[0]) {
            out += e.text;
            cursor[0] = e.id;
        }
    if (progress_version_ != cursor[1]) {
        out +=
            fmt::format("event: progress\ndata: {{\"done\":{},\"total\":{}}}\n\n", done_, total_);
        cursor[1] = progress_version_;
    }
    if (status_version_ != cursor[2]) {
        out += fmt::format("event: status\ndata: {{\"text\":{},\"fraction\":{:.3f}}}\n\n",
                           json_string(status_), status_fraction_);
        cursor[2] = status_version_;
    }
    return out;
}

void PreviewServer::pump(std::span<HttpLoop::StreamNews> news) {
    std::lock_guard<std::mutex> lock(mutex_);
    // Streams at the same place hear the same text: one buffer shared by all of them.
    StreamCursor from{}, to{};
    std::shared_ptr<const std::string> text;
    bool have = false;
    for (HttpLoop::StreamNews& n : news) {
        if (!have || n.cursor != from) {
            from = to = n.cursor;
            std::string t = news_for(to);
            text = t.empty() ? nullptr : std::make_shared<const std::string>(std::move(t));
            have = true;
        }
        n.cursor = to;
        n.text = text;
    }
}

void PreviewServer::push_event(const std::string& type, const std::string& data) {
    const uint64_t id = next_event_++;
    events_.push_back(
        {id, fmt::format("id: {}.{}\nevent: {}\ndata: {}\n\n", event_tag_, id, type, data)});
    if (events_.size() > kKeptEvents) events_.pop_front();
}

void PreviewServer::set_status(const std::string& text, double fraction) {
    status_ = text;
    status_fraction_ = fraction;
    status_at_ = std::chrono::steady_clock::now();
    ++status_version_;
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
        p->stage_serial = stage_serial_;
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
    http_->notify();
}

void PreviewServer::stage(const std::string& what, double fraction) {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        // A piece of work reports often (every BVH build step): its first and last word go
        // out, and between them at most five a second.
        if (what == stage_ && fraction < 1.0 &&
            std::chrono::steady_clock::now() - status_at_ < std::chrono::milliseconds(200))
            return;
        if (what != stage_) {
            stage_ = what;
            ++stage_serial_;
        }
        set_status(what, fraction);
    }
    http_->notify();
}

void PreviewServer::log(const std::string& level, const std::string& text) {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        push_event("log", fmt::format("{{\"level\":{},\"text\":{}}}", json_string(level),
                                      json_string(text)));
    }
    http_->notify();
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
            png_ = std::make_shared<const std::string>(std::move(png));
            ++image_version_;
            push_event("pass", fmt::format("{{\"pass\":{},\"spp\":{},\"target\":{},\"block\":{},"
                                           "\"image\":{}}}",
                                           passes, p->spp, p->target, p->block, image_version_));
            // A pass of work that a newer stage (a reload) has replaced shows its image, but
            // the status line stays with the newer work.
            if (p->stage_serial == stage_serial_)
                set_status(pass_status(passes, p->spp, p->target, p->block), -1.0);
        }
        http_->notify();
    }
}

std::unique_ptr<PreviewServer> start_preview_server(const std::string& spec, const Logger& log) {
    if (spec.empty()) return nullptr;
    auto server = std::make_unique<PreviewServer>(
        spec, [&log](const std::string& line) { log.info("{}", line); });
    fmt::print("live preview at {}\n", server->url());  // even with --quiet: it was asked for
    std::fflush(stdout);
    return server;
}

WorkProgress work_progress_to(PreviewServer* server, WorkProgress inner) {
    if (!server) return inner;
    return [server, inner = std::move(inner)](const std::string& what, double fraction) {
        server->stage(what, fraction);
        if (inner) inner(what, fraction);
    };
}

}  // namespace spangle
