#pragma once
// Stop signals of the render modes. The first SIGINT or SIGTERM asks renders to stop at the next
// wave of tiles and write what they have; a second SIGINT exits at once (status 130), removing
// the temporary file of an image being written (outputs are renamed into place whole, so none is
// ever half-written).

#include <string>

namespace spangle {

/** Installs the handlers of SIGINT and SIGTERM (without SA_RESTART: a blocking wait returns
 *  early when one arrives). */
void install_signal_handlers();

/** Installs the last words of a crash (SIGSEGV, SIGBUS, SIGILL, SIGFPE, SIGABRT): one line on
 *  stderr naming the material plugin, material and kernel the crashing thread was in (or saying
 *  that it was in spangle itself), the temporary file of an image being written removed; then
 *  the signal's default action (exit status 128 + the signal, a core dump where enabled). */
void install_crash_handlers();

/** For commands that write one file and do not poll (merge, denoise): SIGINT, SIGTERM or SIGHUP
 *  (unless ignored, as under nohup) ends the process at once, with one line, the temporary file
 *  of the image being written removed (exit status 130, 143 or 129). */
void install_exit_on_stop_signal();

/** Whether a stop signal has arrived (async-signal-safe to poll from any thread). */
bool stop_requested();

/** Exit status after a stop signal: 0 for SIGINT (the user asked), 128 + 15 for SIGTERM and
 *  128 + 1 for SIGHUP (the terminal closed); 0 when none arrived. */
int exit_status_for_signal();

/** Exit status of a render a stop signal cut short (a partial image, or none): 130 after SIGINT
 *  (as a shell reports an interrupted command), 143 after SIGTERM, 129 after SIGHUP; 0 when
 *  none arrived. A farm
 *  must not take a partial image for a finished one. */
int interrupted_status();

/** "SIGINT" or "SIGTERM": the stop signal that arrived ("" before any). */
const char* stop_signal_name();

/** The end of the line said when a stop signal arrived after the last pass (the image whole):
 *  " (exit status 143, as after any SIGTERM)" for a status that is not 0, else "". */
std::string late_signal_status(int status);

}  // namespace spangle
