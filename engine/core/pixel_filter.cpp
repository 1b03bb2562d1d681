#include "core/pixel_filter.h"

namespace spangle {

bool parse_filter(const std::string& name, FilterKind& out) {
    if (name == "box")
        out = FilterKind::Box;
    else if (name == "gaussian")
        out = FilterKind::Gaussian;
    else if (name == "blackman-harris")
        out = FilterKind::BlackmanHarris;
    else
        return false;
    return true;
}

}  // namespace spangle
