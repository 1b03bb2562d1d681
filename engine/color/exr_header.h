#pragma once
// Reading and copying OpenEXR headers. A copy of a header for a new scanline file: every attribute
// of the original but those that describe how the original was stored (tiles, parts), which a
// scanline file written with the copy must not claim (a tiled part's header, copied whole, made a
// merged or denoised file that said "tiles" over scanline data: unreadable, written with exit
// status 0).

#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfStringAttribute.h>

#include <algorithm>
#include <initializer_list>
#include <string>

namespace spangle {

/** The string attribute `name` of a header ("" when it has none or it is not a string). */
inline std::string string_attribute(const Imf::Header& h, const char* name) {
    const auto* a = h.findTypedAttribute<Imf::StringAttribute>(name);
    return a ? a->value() : std::string();
}

/** `from` as a scanline image's header, without the attributes named in `drop` (copied one by
 *  one: OpenEXR 3.1's Header::erase leaks the attribute it removes). Channels are kept. */
inline Imf::Header scanline_header(const Imf::Header& from,
                                   std::initializer_list<const char*> drop = {}) {
    Imf::Header header(from.displayWindow(), from.dataWindow());
    for (auto it = from.begin(); it != from.end(); ++it) {
        const std::string name = it.name();
        if (name == "tiles" || name == "type" || name == "chunkCount" || name == "name" ||
            name == "version" ||
            std::any_of(drop.begin(), drop.end(), [&](const char* d) { return name == d; }))
            continue;
        header.insert(name, it.attribute());
    }
    return header;
}

}  // namespace spangle
