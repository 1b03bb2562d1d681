// What the render modes share: see render_setup.h.

#include "cli/render_setup.h"

#include "cli/signals.h"

namespace spangle {

RenderSetup set_up_render(const RenderArgs& a, bool scene_names_output) {
    // (Without -o, a mode that reads the scene's own output checks its default once it knows it
    // is the one: scene_outputs().)
    const bool deferred = scene_names_output && a.output.empty();
    RenderSetup s{render_logger(a), outputs_for(a, !deferred)};
    if (!deferred) s.out.remove_stale_temporaries(s.log);
    install_signal_handlers();
    return s;
}

void warn_nonfinite(const Logger& log, const RenderStats& st) {
    if (st.nonfinite > 0)
        log.warn(
            "{} non-finite sample values were replaced by black; the first at pixel ({}, {}), "
            "sample {}",
            st.nonfinite, st.first_bad_pixel_x, st.first_bad_pixel_y, st.first_bad_sample);
    for (const std::string& p : st.plugin_problems) log.warn("{}", p);
}

}  // namespace spangle
