// Stop signals: see signals.h.

#include "cli/signals.h"

#include <fcntl.h>
#include <unistd.h>

#include <csignal>

#include "cli/outputs.h"
#include "color/image_output.h"
#include "shading/plugin_call.h"

namespace spangle {
namespace {

/** The first stop signal that arrived (SIGINT, SIGTERM or SIGHUP), 0 before any. */
volatile std::sig_atomic_t stop_signal = 0;

/** /dev/null, opened when the handlers are installed, and whether stdout and stderr were
 *  terminals then: after SIGHUP (the terminal closed) every write to it fails (EIO), and a
 *  progress line or the "stopped by a signal" warning threw out of the render: it ended in
 *  std::terminate, without its partial image. */
int dev_null = -1;
bool out_tty = false, err_tty = false;

/** Points stdout and stderr that were the terminal at /dev/null (async-signal-safe). */
void detach_from_terminal() {
    if (dev_null < 0) return;
    if (out_tty) ::dup2(dev_null, STDOUT_FILENO);
    if (err_tty) ::dup2(dev_null, STDERR_FILENO);
}

void remember_terminal() {
    if (dev_null < 0) dev_null = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
    out_tty = ::isatty(STDOUT_FILENO) != 0;
    err_tty = ::isatty(STDERR_FILENO) != 0;
}

extern "C" void on_stop_signal(int sig) {
    if (sig == SIGHUP) detach_from_terminal();
    if (sig == SIGINT && stop_signal == SIGINT) {
        // Said (it exited without a word, and the old file at the output's path could be
        // taken for this render's), and nothing of the write left behind.
        const bool writing = remove_image_in_progress();
        remove_locks_in_progress();
        say_to_stderr(
            writing ? "\nspangle: stopped at once by a second SIGINT while writing: that image "
                      "was not written (a file already at its path is an older one)\n"
                    : "\nspangle: stopped at once by a second SIGINT: nothing more written\n");
        ::_exit(130);
    }
    if (stop_signal == 0) stop_signal = sig;
}

extern "C" void on_crash(int sig) {
    say_fatal_signal(sig, true);
    remove_image_in_progress();
    // The default action: the status and the core dump the signal would have given.
    std::signal(sig, SIG_DFL);
    ::raise(sig);
}

extern "C" void on_stop_exit(int sig) {
    if (sig == SIGHUP) detach_from_terminal();
    say_to_stderr(sig == SIGINT   ? "spangle: stopped by SIGINT: nothing written\n"
                  : sig == SIGHUP ? "spangle: stopped by SIGHUP: nothing written\n"
                                  : "spangle: stopped by SIGTERM: nothing written\n");
    remove_image_in_progress();
    remove_locks_in_progress();
    ::_exit(128 + sig);
}

/** Installs `sa` for SIGINT, SIGTERM and SIGHUP (the terminal closed: it killed the render,
 *  leaving its temporary file and lock behind), but not over a SIGHUP that is ignored (nohup
 *  renders go on when the terminal closes). */
void install_stop(const struct sigaction& sa) {
    remember_terminal();
    sigaction(SIGINT, &sa, nullptr);
    sigaction(SIGTERM, &sa, nullptr);
    struct sigaction hup {};
    if (sigaction(SIGHUP, nullptr, &hup) == 0 && hup.sa_handler != SIG_IGN)
        sigaction(SIGHUP, &sa, nullptr);
}

}  // namespace

void install_exit_on_stop_signal() {
    struct sigaction sa {};
    sa.sa_handler = on_stop_exit;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = 0;
    install_stop(sa);
}

void install_crash_handlers() {
    // A file-size limit (ulimit -f) makes a write fail with EFBIG, an error every command
    // reports and cleans up after, instead of killing the process with its temporary file left.
    std::signal(SIGXFSZ, SIG_IGN);
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
    return;  // the sanitizer's own report says more
#endif
    struct sigaction sa {};
    sa.sa_handler = on_crash;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESETHAND;  // a crash inside the handler takes the default action
    for (const int sig : {SIGSEGV, SIGBUS, SIGILL, SIGFPE, SIGABRT}) sigaction(sig, &sa, nullptr);
}

void install_signal_handlers() {
    struct sigaction sa {};
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = 0;  // no SA_RESTART: a blocking wait returns early
    install_stop(sa);
    // A file-size limit (ulimit -f) makes the write fail with EFBIG, an error Spangle reports
    // and cleans up after, instead of killing the process with its temporary file left.
    std::signal(SIGXFSZ, SIG_IGN);
}

bool stop_requested() {
    return stop_signal != 0;
}

int interrupted_status() {
    return stop_signal != 0 ? 128 + static_cast<int>(stop_signal) : 0;
}

const char* stop_signal_name() {
    return stop_signal == SIGINT    ? "SIGINT"
           : stop_signal == SIGTERM ? "SIGTERM"
           : stop_signal == SIGHUP  ? "SIGHUP"
                                    : "";
}

std::string late_signal_status(int status) {
    if (status == 0) return {};
    return " (exit status " + std::to_string(status) + ", as after any " + stop_signal_name() + ")";
}

int exit_status_for_signal() {
    return stop_signal == SIGTERM || stop_signal == SIGHUP ? 128 + static_cast<int>(stop_signal)
                                                           : 0;
}

}  // namespace spangle
