#include "shading/plugin_call.h"

#include <fmt/format.h>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <csignal>
#include <iterator>
#include <vector>

namespace spangle {

namespace {

thread_local PluginCallSite t_call;

bool finite_nonnegative(float x) {
    return std::isfinite(x) && x >= 0.0f;
}

/** True when all three channels are finite and at least 0. */
bool finite_nonnegative(const float v[3]) {
    return finite_nonnegative(v[0]) && finite_nonnegative(v[1]) && finite_nonnegative(v[2]);
}

/** The glint outputs of a sample() or eval() call (null when not asked for). */
struct Glints {
    float *r, *g, *b;
    /** Query k's glint set to 0 (its f was dropped). */
    void clear(uint32_t k) const {
        if (r) r[k] = g[k] = b[k] = 0.0f;
    }
    /** Query k's glint clamped into [0, f] per channel; true when a channel was outside. */
    bool clamp(uint32_t k, const float f[3]) const {
        if (!r) return false;
        bool outside = false;
        float* const ch[3] = {r, g, b};
        for (int c = 0; c < 3; ++c) {
            const float v = ch[c][k];
            if (v >= 0.0f && v <= f[c]) continue;
            ch[c][k] = std::isnan(v) ? 0.0f : std::clamp(v, 0.0f, f[c]);
            outside = true;
        }
        return outside;
    }
};

}  // namespace

PluginCallSite current_plugin_call() noexcept {
    return t_call;
}

namespace {

constexpr int kFatalSignals[] = {SIGSEGV, SIGBUS, SIGILL, SIGFPE, SIGABRT};
struct sigaction g_before[std::size(kFatalSignals)];
std::atomic<bool> g_naming{false};

extern "C" void on_fatal_in_host(int sig) {
    if (current_plugin_call().label) say_fatal_signal(sig, false);
    for (std::size_t i = 0; i < std::size(kFatalSignals); ++i)
        if (kFatalSignals[i] == sig) {
            sigaction(sig, &g_before[i], nullptr);
            break;
        }
    ::raise(sig);
}

}  // namespace

void say_to_stderr(const char* text) noexcept {
    std::size_t n = 0;
    while (text[n]) ++n;
    while (n > 0) {
        const ssize_t w = ::write(STDERR_FILENO, text, n);
        if (w <= 0) return;
        text += w;
        n -= static_cast<std::size_t>(w);
    }
}

void say_fatal_signal(int sig, bool outside) noexcept {
    const char* what = sig == SIGSEGV   ? "SIGSEGV (invalid memory access)"
                       : sig == SIGBUS  ? "SIGBUS (a mapped file changed or vanished)"
                       : sig == SIGILL  ? "SIGILL (illegal instruction)"
                       : sig == SIGFPE  ? "SIGFPE (arithmetic fault)"
                       : sig == SIGABRT ? "SIGABRT (aborted)"
                                        : "a fatal signal";
    const PluginCallSite call = current_plugin_call();
    if (call.label && call.kernel) {
        say_to_stderr("spangle: fatal: ");
        say_to_stderr(what);
        say_to_stderr(" in ");
        say_to_stderr(call.kernel);
        say_to_stderr("() of ");
        say_to_stderr(call.label);
        say_to_stderr(
            ": the plugin crashed (rebuild it, or report it to its author with the scene)\n");
    } else if (outside) {
        say_to_stderr("spangle: fatal: ");
        say_to_stderr(what);
        say_to_stderr(
            " in spangle itself: please report it, with the scene and the command line\n");
    }
}

void name_plugin_crashes() noexcept {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
    return;  // the sanitizer's own report says more
#endif
    if (g_naming.exchange(true)) return;
    struct sigaction sa {};
    sa.sa_handler = on_fatal_in_host;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_ONSTACK;
    for (std::size_t i = 0; i < std::size(kFatalSignals); ++i)
        sigaction(kFatalSignals[i], &sa, &g_before[i]);
}

PluginCallMark::PluginCallMark(const char* label, const char* kernel) noexcept : saved_(t_call) {
    t_call = {kernel, label};
}

PluginCallMark::~PluginCallMark() {
    t_call = saved_;
}

std::string BadOutputCounts::take_report() {
    const std::pair<std::atomic<uint64_t>*, const char*> kinds[] = {
        {&direction, "a sampled direction not finite or zero"},
        {&density, "a pdf not finite, negative, or 0 with a positive f"},
        {&value, "an f negative or not finite"},
        {&side, "a reflection leaving on the other side (or a transmission on the same side)"},
        {&glint, "a glint outside [0, f] (clamped)"}};
    std::vector<std::string> parts;
    for (const auto& [count, what] : kinds)
        if (const uint64_t n = count->exchange(0); n > 0)
            parts.push_back(fmt::format("{} x {}", n, what));
    return fmt::format("{}", fmt::join(parts, "; "));
}

void check_samples(SpangleSampleBatch_v3& s, const float* wo_z, uint32_t n, BadOutputCounts& bad) {
    uint64_t direction = 0, density = 0, value = 0, side = 0, glint = 0;
    const Glints glints{s.glint_r, s.glint_g, s.glint_b};
    for (uint32_t k = 0; k < n; ++k) {
        if (s.flags[k] == 0) continue;
        const float x = s.wi_x[k], y = s.wi_y[k], z = s.wi_z[k];
        const float f[3] = {s.f_r[k], s.f_g[k], s.f_b[k]};
        const float len2 = x * x + y * y + z * z;
        bool ok = true;
        if (!std::isfinite(len2) || !(len2 > 0.0f)) {
            ++direction;
            ok = false;
        } else if (!finite_nonnegative(f)) {
            ++value;
            ok = false;
        } else if (!std::isfinite(s.pdf[k]) ||
                   (!(s.pdf[k] > 0.0f) && std::max({f[0], f[1], f[2]}) > 0.0f)) {
            ++density;
            ok = false;
        } else {
            // The side wi leaves on against the lobe the plugin says it drew (wo.z exactly 0 or
            // wi.z exactly 0 says nothing).
            const float facing = z * wo_z[k];
            const bool reflection = (s.flags[k] & SPANGLE_SAMPLE_REFLECTION) != 0,
                       transmission = (s.flags[k] & SPANGLE_SAMPLE_TRANSMISSION) != 0;
            if ((reflection && !transmission && facing < 0.0f) ||
                (transmission && !reflection && facing > 0.0f)) {
                ++side;
                ok = false;
            }
        }
        if (!ok) {
            s.flags[k] = 0;
            s.f_r[k] = s.f_g[k] = s.f_b[k] = s.pdf[k] = 0.0f;
            glints.clear(k);
            continue;
        }
        glint += glints.clamp(k, f) ? 1 : 0;
    }
    if (direction) bad.direction += direction;
    if (density) bad.density += density;
    if (value) bad.value += value;
    if (side) bad.side += side;
    if (glint) bad.glint += glint;
}

void check_evals(SpangleEvalBatch_v3& e, uint32_t n, BadOutputCounts& bad) {
    uint64_t density = 0, value = 0, glint = 0;
    const Glints glints{e.glint_r, e.glint_g, e.glint_b};
    for (uint32_t k = 0; k < n; ++k) {
        const float f[3] = {e.f_r[k], e.f_g[k], e.f_b[k]};
        const bool f_ok = finite_nonnegative(f);
        if (!f_ok || !finite_nonnegative(e.pdf[k])) {
            ++(f_ok ? density : value);
            e.f_r[k] = e.f_g[k] = e.f_b[k] = e.pdf[k] = 0.0f;
            glints.clear(k);
            continue;
        }
        glint += glints.clamp(k, f) ? 1 : 0;
    }
    if (density) bad.density += density;
    if (value) bad.value += value;
    if (glint) bad.glint += glint;
}

}  // namespace spangle
