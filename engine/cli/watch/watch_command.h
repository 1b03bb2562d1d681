#pragma once
// Watch mode, `spangle render --watch`: the look-development loop. This folder holds what only
// it uses: the loop (watch_command.cpp) and the inotify file watcher (file_watcher.h). The live
// preview page it feeds (cli/preview_server.h) serves `render --serve` too and lives beside the
// other render modes.

#include "cli/render_args.h"

namespace spangle {

/** Renders, then watches every input (the scene and every file it was built from) and
 *  re-renders incrementally on each save until a stop signal. Passes are written as they end
 *  unless --no-pass-output; a reload line per change says what changed and ran, and when the
 *  first pass after it was written. A failed reload keeps the last good scene. Returns the exit
 *  status after the signal; throws UsageError or SpangleError for a bad start. */
int run_watch(const RenderArgs& a);

}  // namespace spangle
