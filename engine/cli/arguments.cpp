// Command-line values CLI11 cannot check alone: see arguments.h.

#include "cli/arguments.h"

#include "cli/usage.h"

namespace spangle {

bool pixel_count(const std::string& t, uint32_t& value) {
    if (t.empty() || t.size() > 5 || t.find_first_not_of("0123456789") != std::string::npos)
        return false;
    value = static_cast<uint32_t>(std::stoul(t));
    return true;
}

void parse_size(const std::string& size, uint32_t& width, uint32_t& height) {
    const auto x = size.find('x');
    const auto side = [&](const std::string& t) -> uint32_t {
        uint32_t v = 0;
        return pixel_count(t, v) ? v : 0;
    };
    width = x == std::string::npos ? 0 : side(size.substr(0, x));
    height = x == std::string::npos ? 0 : side(size.substr(x + 1));
    if (width < 1 || height < 1 || width > 16384 || height > 16384)
        usage_error("--size must be WIDTHxHEIGHT with each in 1..16384, got '{}'", size);
}

CropWindow parse_crop(const std::string& text) {
    uint32_t v[4] = {0, 0, 0, 0};
    std::size_t at = 0;
    for (int i = 0; i < 4; ++i) {
        const std::size_t end = i < 3 ? text.find(',', at) : text.size();
        const std::string t = end == std::string::npos ? std::string() : text.substr(at, end - at);
        if (!pixel_count(t, v[i]))
            usage_error(
                "--crop must be x0,y0,x1,y1 (pixels, the window [x0, x1) x [y0, y1)), got '{}'",
                text);
        at = end + 1;
    }
    if (!(v[0] < v[2] && v[1] < v[3])) usage_error("--crop {}: it needs x0 < x1 and y0 < y1", text);
    return CropWindow{v[0], v[1], v[2], v[3]};
}

void parse_spp_range(const std::string& text, uint32_t& first, uint32_t& end) {
    const auto number = [](const std::string& t, uint32_t& v) {
        if (t.empty() || t.size() > 7 || t.find_first_not_of("0123456789") != std::string::npos)
            return false;
        v = static_cast<uint32_t>(std::stoul(t));
        return v <= (1u << 20);
    };
    const std::size_t dots = text.find("..");
    if (dots == std::string::npos || !number(text.substr(0, dots), first) ||
        !number(text.substr(dots + 2), end))
        usage_error("--spp-range must be A..B (sample numbers, samples A to B-1), got '{}'", text);
    if (!(first < end)) usage_error("--spp-range {}: it needs A < B", text);
}

std::pair<int64_t, int64_t> parse_frames(const std::string& text) {
    const auto number = [&](const std::string& t) -> int64_t {
        const std::size_t digits = t.find_first_not_of("-0123456789");
        if (t.empty() || t.size() > 10 || digits != std::string::npos ||
            t.find('-', 1) != std::string::npos || t == "-")
            usage_error("--frames must be A..B or A (frame numbers), got '{}'", text);
        return std::stoll(t);
    };
    const std::size_t dots = text.find("..");
    const int64_t a = number(dots == std::string::npos ? text : text.substr(0, dots));
    const int64_t b = dots == std::string::npos ? a : number(text.substr(dots + 2));
    if (b < a) usage_error("--frames {}: the last frame comes before the first", text);
    if (b - a >= 1000000) usage_error("--frames {}: more than a million frames", text);
    return {a, b};
}

}  // namespace spangle
