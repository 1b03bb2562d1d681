// Stop signals: see signals.h.

#include "cli/signals.h"

#include <unistd.h>

#include <csignal>

#include "color/image_output.h"

namespace spangle {
namespace {

/** The first stop signal that arrived (SIGINT or SIGTERM), 0 before any. */
volatile std::sig_atomic_t stop_signal = 0;

extern "C" void on_stop_signal(int sig) {
    if (sig == SIGINT && stop_signal == SIGINT) {
        remove_image_in_progress();
        ::_exit(130);
    }
    if (stop_signal == 0) stop_signal = sig;
}

}  // namespace

void install_signal_handlers() {
    struct sigaction sa {};
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = 0;  // no SA_RESTART: a blocking wait returns early
    sigaction(SIGINT, &sa, nullptr);
    sigaction(SIGTERM, &sa, nullptr);
    // A file-size limit (ulimit -f) makes the write fail with EFBIG, an error Spangle reports
    // and cleans up after, instead of killing the process with its temporary file left.
    std::signal(SIGXFSZ, SIG_IGN);
}

bool stop_requested() {
    return stop_signal != 0;
}

const char* stop_signal_name() {
    return stop_signal == SIGINT ? "SIGINT" : stop_signal == SIGTERM ? "SIGTERM" : "";
}

int exit_status_for_signal() {
    return stop_signal == SIGTERM ? 143 : 0;
}

}  // namespace spangle
