#pragma once
// The scene's OpenColorIO config and working space. OCIO exceptions stop here: every failure
// becomes a SpangleError naming the colour spaces involved.

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace spangle {

/** CIE xy chromaticities of a colour space's primaries and white, as OpenEXR stores them. */
struct Chromaticities {
    std::array<float, 8> xy;  ///< red x,y, green x,y, blue x,y, white x,y
};

/** An OCIO config plus the chosen working space. Cheap to pass by reference; not copyable. */
class ColorConfig {
public:
    /** Loads the config: `path` when non-empty, else $OCIO, else the first existing of
     *  `fallbacks`. Throws SpangleError naming each place tried. */
    static ColorConfig load(const std::string& path, const std::vector<std::string>& fallbacks);

    ColorConfig(ColorConfig&&) noexcept;
    ColorConfig& operator=(ColorConfig&&) noexcept;
    ~ColorConfig();

    /** Path of the loaded config file. */
    const std::string& path() const;
    /** A second handle on the same loaded config with its own working space (a watch session
     *  parses an edited scene into one, so that a failed parse changes nothing). */
    ColorConfig clone() const;
    /** Canonical name of a colour space (aliases resolved), or nullopt when unknown. */
    std::optional<std::string> canonical_name(const std::string& space) const;
    /** All colour space names, for error messages. */
    std::vector<std::string> space_names() const;

    /** Sets the working space; throws SpangleError if the config does not define it. */
    void set_working_space(const std::string& space);
    const std::string& working_space() const;

    /** Converts count RGB triples in place from `from` to `to`. Throws SpangleError. */
    void convert(const std::string& from, const std::string& to, float* rgb,
                 std::size_t count) const;
    /** Converts in place from `from` to the working space. */
    void to_working(const std::string& from, float* rgb, std::size_t count) const {
        convert(from, working_space(), rgb, count);
    }
    /** Applies display/view to count RGB triples in the working space, in place. */
    void to_display(const std::string& display, const std::string& view, float* rgb,
                    std::size_t count) const;
    /** Default display and its default view. */
    std::string default_display() const;
    std::string default_view(const std::string& display) const;

    /** Chromaticities of the working space, when known (see the .cpp for how). */
    std::optional<Chromaticities> working_chromaticities() const;

private:
    struct Impl;
    explicit ColorConfig(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> impl_;
};

}  // namespace spangle
