#pragma once
// What the render modes share around a render: the start of a one-process render (its logger,
// its outputs checked before any work, the stop signals) and the note of non-finite samples.

#include "cli/outputs.h"
#include "cli/render_args.h"
#include "core/log.h"
#include "render/render_options.h"

namespace spangle {

/** What a one-process render (one-shot, --frames, --watch) starts with. */
struct RenderSetup {
    Logger log;   ///< render_logger(args)
    Outputs out;  ///< outputs_for(args)
};

/** Sets a one-process render up, in this order: the logger, the outputs (checked before any
 *  work: UsageError or SpangleError; temporary images a killed render left in their folders
 *  removed), then the stop signals' handlers. `scene_names_output`: the mode replaces the
 *  outputs by scene_outputs() once the scene is read, so a default (no -o) is not checked yet. */
RenderSetup set_up_render(const RenderArgs& a, bool scene_names_output = false);

/** Says how many sample values were non-finite and replaced by black, and the first of them
 *  (pixel and sample); nothing when there were none. */
void warn_nonfinite(const Logger& log, const RenderStats& st);

}  // namespace spangle
