#pragma once
// Calls into a material plugin: which call a thread is in (the fatal-signal handler's last words
// name the plugin, the material and the kernel), a C++ exception that escaped the plugin turned
// into an error naming them, and the outputs of eval() and sample() checked before the
// integrator trusts them.

#include <spangle/plugin.h>

#include <atomic>
#include <cstdint>
#include <string>

#include "core/error.h"

namespace spangle {

/** A plugin call in progress: the kernel ("eval") and who is called ("plugin 'x' (path),
 *  material 'm'"). Both are plain C strings that outlive the call. */
struct PluginCallSite {
    const char* kernel = nullptr;
    const char* label = nullptr;
};

/** The plugin call this thread is in (both null outside any). Async-signal-safe to read. */
PluginCallSite current_plugin_call() noexcept;

/** write(2) of a C string to stderr, ignoring the result (nothing else can be done in a signal
 *  handler). Async-signal-safe. */
void say_to_stderr(const char* text) noexcept;

/** The last words of a fatal signal `sig` (SIGSEGV, SIGBUS, ...) on stderr: "spangle: fatal:
 *  SIGSEGV (...) in eval() of plugin 'x' (path), material 'm': the plugin crashed (...)" when
 *  this thread is in a plugin call, else (with `outside`) that it happened in spangle itself.
 *  Async-signal-safe: for a signal handler. */
void say_fatal_signal(int sig, bool outside) noexcept;

/** For a library loaded into another program (the Python module): fatal signals in a plugin
 *  call are named (say_fatal_signal), then handed to the handler they had before (Python's
 *  faulthandler, or the default action: the process dies as it would have). Signals outside a
 *  plugin call go straight to that handler. Idempotent. */
void name_plugin_crashes() noexcept;

/** Marks this thread as inside a plugin call for its lifetime (nesting restores the outer one). */
class PluginCallMark {
public:
    PluginCallMark(const char* label, const char* kernel) noexcept;
    ~PluginCallMark();
    PluginCallMark(const PluginCallMark&) = delete;
    PluginCallMark& operator=(const PluginCallMark&) = delete;

private:
    PluginCallSite saved_;
};

/** Runs f() (a call into the plugin) marked as `kernel` of `label`; an exception that escapes
 *  it becomes a SpangleError naming them (a plugin must not throw: the ABI is C). */
template <class F>
void call_plugin(const std::string& label, const char* kernel, F&& f) {
    PluginCallMark mark(label.c_str(), kernel);
    try {
        f();
    } catch (const SpangleError&) {
        throw;  // the host's own, from a callback (already says what it is about)
    } catch (const std::exception& e) {
        throw_error("{}: {}() threw an exception (a plugin must not throw across the C ABI): {}",
                    label, kernel, e.what());
    } catch (...) {
        throw_error("{}: {}() threw an exception (a plugin must not throw across the C ABI)", label,
                    kernel);
    }
}

/** Outputs of a plugin the host could not use, counted per material over a render. */
struct BadOutputCounts {
    std::atomic<uint64_t> direction{0};  ///< sample(): wi not finite, or zero
    std::atomic<uint64_t> density{0};    ///< pdf not finite or negative (sample: <= 0 with f > 0)
    std::atomic<uint64_t> value{0};      ///< f negative or not finite
    std::atomic<uint64_t> side{0};       ///< sample(): reflection/transmission against wi's side
    std::atomic<uint64_t> glint{0};      ///< glint outside [0, f]
    /** Empty when nothing was counted, else what and how many (and zeroes the counts). */
    std::string take_report();
};

/** Checks the first n samples of a sample() call whose closures saw wo_z: an unusable sample
 *  (wi not finite or zero, pdf not finite or <= 0 while f > 0, f negative or not finite, a
 *  reflection that leaves on the other side from wo or a transmission on the same side) gets
 *  flags 0, and a glint is clamped into [0, f]; each is counted. */
void check_samples(SpangleSampleBatch_v3& s, const float* wo_z, uint32_t n, BadOutputCounts& bad);

/** Checks the first n results of an eval() call: f negative or not finite, or a pdf not finite
 *  or negative, zeroes the query (f, pdf and glint); a glint is clamped into [0, f]. */
void check_evals(SpangleEvalBatch_v3& e, uint32_t n, BadOutputCounts& bad);

}  // namespace spangle
