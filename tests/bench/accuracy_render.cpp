#include "accuracy_render.h"

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.h"
#include "core/files.h"
#include "shading/material.h"
#include "shading/plugin_loader.h"
#include "test_support.h"

namespace spangle::accuracy {
namespace {

using Clock = std::chrono::steady_clock;

/** Splits an inline table's body ("a = 1, b = [1, 2]") at the commas outside brackets and
 *  quotes into (key, value) pairs. */
std::vector<std::pair<std::string, std::string>> split_table(const std::string& body) {
    std::vector<std::pair<std::string, std::string>> out;
    int depth = 0;
    bool quoted = false;
    std::string item;
    const auto flush = [&] {
        const auto eq = item.find('=');
        if (eq != std::string::npos)
            out.emplace_back(trim(item.substr(0, eq)), trim(item.substr(eq + 1)));
        item.clear();
    };
    for (char c : body) {
        if (c == '"') quoted = !quoted;
        if (!quoted && c == '[') ++depth;
        if (!quoted && c == ']') --depth;
        if (!quoted && depth == 0 && c == ',')
            flush();
        else
            item += c;
    }
    flush();
    return out;
}

/** A flake material's `params = { ... }` line with the edit's parameters set. */
std::string edit_params(const std::string& line, const SceneEdit& e) {
    const auto open = line.find('{'), close = line.rfind('}');
    if (open == std::string::npos || close == std::string::npos || close < open)
        throw_error("cannot edit flake parameters in '{}'", line);
    auto params = split_table(line.substr(open + 1, close - open - 1));
    const auto set = [&](const std::string& key, const std::string& value) {
        for (auto& [k, v] : params)
            if (k == key) {
                v = value;
                return;
            }
        params.emplace_back(key, value);
    };
    if (e.gamma_scale != 1.0) {
        double gamma = 3.0;  // the plugin's default
        for (const auto& [k, v] : params)
            if (k == "gamma") gamma = std::stod(v);
        set("gamma", fmt::format("{}", gamma * e.gamma_scale));
    }
    for (const auto& [k, v] : e.flake) set(k, v);
    std::string out = "params = {";
    for (std::size_t i = 0; i < params.size(); ++i)
        out += fmt::format("{} {} = {}", i ? "," : "", params[i].first, params[i].second);
    return out + " }";
}

RenderOptions options(int threads) {
    RenderOptions o;
    o.threads = threads;
    return o;
}

}  // namespace

std::string trim(const std::string& s) {
    const auto a = s.find_first_not_of(" \t\r");
    if (a == std::string::npos) return {};
    return s.substr(a, s.find_last_not_of(" \t\r") - a + 1);
}

std::string edit_scene(const std::string& shipped, const std::string& scene_dir,
                       const SceneEdit& e) {
    std::map<std::string, std::string> render_keys = {{"width", fmt::format("{}", e.width)},
                                                      {"height", fmt::format("{}", e.height)},
                                                      {"seed", fmt::format("{}", e.seed)}};
    if (e.clamp) render_keys["clamp_indirect"] = fmt::format("{}", *e.clamp);
    std::istringstream in(shipped);
    std::string out, line, section;
    bool flake = false;
    int edited = 0;
    while (std::getline(in, line)) {
        const std::string t = trim(line);
        if (!t.empty() && t[0] == '[') {
            section = t;
            flake = false;
            out += line + '\n';
            if (t == "[render]")
                for (const auto& [k, v] : render_keys) out += fmt::format("{} = {}\n", k, v);
            continue;
        }
        const std::string key = trim(t.substr(0, t.find('=')));
        if (section == "[render]" && render_keys.count(key)) continue;
        if (section == "[[material]]" && key == "plugin")
            flake = t.find("\"flake\"") != std::string::npos;
        if (flake && key == "params") {
            line = edit_params(t, e);
            ++edited;
        }
        for (std::size_t at = line.find("\"../"); at != std::string::npos;
             at = line.find("\"../", at + scene_dir.size()))
            line.insert(at + 1, scene_dir + "/");
        out += line + '\n';
    }
    if (edited == 0) throw_error("the scene has no flake material to edit");
    return out;
}

double seconds_since(Clock::time_point t0) {
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

std::string plugins_fingerprint() {
    // Each library's file name and content hash, in the search path's order (the loader's own:
    // the first file of each name is the one opened).
    std::string out;
    for (const std::string& path : PluginLoader(plugin_search_path({})).discover()) {
        const uint64_t h = file_content_hash(path);
        if (h == 0) throw_error("cannot read the plugin '{}'", path);
        out += fmt::format("{}:{:016x}\n", std::filesystem::path(path).filename().string(), h);
    }
    return out;
}

Renderer::Renderer(std::string work_file, int threads)
    : file_(std::move(work_file)),
      session_({}, test::shipped_ocio(), options(threads), test::quiet_log()) {}

void Renderer::load(const std::string& text) {
    if (text == text_) return;
    {
        std::ofstream f(file_);
        f << text;
        if (!f) throw_error("cannot write '{}'", file_);
    }
    text_.clear();  // a failed load leaves no scene this object would take for the live one
    session_.load(file_);
    text_ = text;
}

Image Renderer::render(uint32_t spp, Strategy strategy) {
    RenderOptions& o = session_.options();
    o.spp_override = spp;
    o.strategy = strategy;
    o.progressive = false;
    o.on_pass = {};
    session_.render();
    return {session_.result().width, session_.result().height, session_.result().image};
}

std::vector<Pass> Renderer::render_passes(uint32_t spp, Strategy strategy) {
    render(kWarmUpSpp, strategy);
    RenderOptions& o = session_.options();
    o.spp_override = spp;
    o.progressive = true;
    std::vector<Pass> passes;
    double in_callback = 0;  // copying the pass images is not rendering
    const auto t0 = Clock::now();
    o.on_pass = [&](const PassImage& p) {
        const auto t = Clock::now();
        passes.push_back(
            {p.spp, seconds_since(t0) - in_callback, Image{p.width, p.height, p.image}});
        in_callback += seconds_since(t);
    };
    session_.render();
    const double total = seconds_since(t0) - in_callback;
    o.on_pass = {};
    passes.push_back(
        {spp, total,
         Image{session_.result().width, session_.result().height, session_.result().image}});
    return passes;
}

std::map<std::string, double> Renderer::material_stats() {
    std::map<std::string, double> out;
    for (const auto& mat : session_.world().products.get<MaterialSet>().instances) {
        if (!mat || !mat->model().stats) continue;
        SpangleStat_v3 buf[64];
        const uint32_t n = std::min<uint32_t>(mat->model().stats(mat->instance(), buf, 64), 64);
        for (uint32_t i = 0; i < n; ++i)
            if (buf[i].name) out[buf[i].name] = buf[i].value;
        break;
    }
    return out;
}

}  // namespace spangle::accuracy
