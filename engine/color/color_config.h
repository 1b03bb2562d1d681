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
/** A colour space found in the config. */
struct ResolvedSpace {
    std::string name;  ///< canonical name in the config
    std::string via;  ///< empty, or what stood in for a missing name ("its scene_linear role, ...")
};

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
    /** Canonical name of a colour space (aliases resolved), or nullopt when unknown (a named
     *  transform is no colour space). */
    std::optional<std::string> canonical_name(const std::string& space) const;
    /** Whether `name` is one of the config's named transforms (OCIO 2.1). */
    bool is_named_transform(const std::string& name) const;
    /** Whether `space` names a data space of the config (OCIO's isdata: "Non-Color", "Utility -
     *  Raw"): its values are numbers, not colours. False for an unknown name. */
    bool is_data(const std::string& space) const;
    /** Like canonical_name, but a name of Spangle's own config (ACEScg, lin_rec709,
     *  srgb_texture, raw) missing from a foreign config falls back to a common name for the same
     *  space, then to the role for that kind of space (scene_linear, color_picking, data...). */
    std::optional<ResolvedSpace> resolve(const std::string& space) const;
    /** What to do about an unknown colour space in this config (mentions $OCIO when the config
     *  came from it). */
    std::string how_to_fix() const;
    /** All colour space names, for error messages. */
    std::vector<std::string> space_names() const;

    /** Why `space` (a name the config has) cannot hold light as it adds up: a data space, a
     *  display-referred one, an encoding other than scene-linear ("its encoding is
     *  sdr-video"), or, where the config names no encoding, a transform to the reference that
     *  is not linear on test colours (a log or gamma curve). Nothing for a linear space. Throws
     *  SpangleError when the space's transform cannot be made (a missing LUT file). */
    std::optional<std::string> not_scene_linear(const std::string& space) const;
    /** Sets the working space; throws SpangleError if the config does not define it. */
    void set_working_space(const std::string& space);
    const std::string& working_space() const;
    /** The working space a scene that names none renders in: the config's scene_linear role's
     *  space (empty without the role), whatever set_working_space() set since. */
    const std::string& default_working_space() const;

    /** An identity of the conversion from `from` to `to` as this config defines it
     *  (OpenColorIO's processor cache id: equal for equal transforms, whatever the config's
     *  path). Throws SpangleError. */
    std::string conversion_id(const std::string& from, const std::string& to) const;
    /** A hash of the config's text as loaded (its spaces, roles, displays and looks) and of the
     *  bytes of the LUT files the scene's conversions (colours, textures, the working space's
     *  test; not the preview's display) have read so far: equal on every machine that loads an
     *  equal config with equal LUTs. */
    uint64_t content_hash() const;
    /** The files (LUTs) this config's conversions have read, resolved by its search path and
     *  context ($SHOT...). */
    std::vector<std::string> lut_files() const;
    /** Whether one of lut_files() has changed since a conversion first read it. */
    bool lut_files_changed() const;
    /** Drops OpenColorIO's caches of files read (LUTs), so that the next processors read them
     *  afresh: for a config reloaded after an edit. */
    static void forget_read_files();
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
    /** Fills an empty display or view with the config's default (the display's default view)
     *  and checks both exist; throws SpangleError listing the displays or the display's views. */
    void resolve_view(std::string& display, std::string& view) const;
    /** Default display and its default view. */
    /** Whether the display and view (empty: the defaults) encode for an sRGB display: the
     *  display or the view's colour space names sRGB, and the view is not of data (Raw). A PNG
     *  of any other is not tagged sRGB. */
    bool view_is_srgb(const std::string& display, const std::string& view) const;
    std::string default_display() const;
    std::string default_view(const std::string& display) const;

    /** Chromaticities of the working space, when known (see the .cpp for how). */
    std::optional<Chromaticities> working_chromaticities() const;

private:
    struct Impl;
    explicit ColorConfig(std::unique_ptr<Impl> impl);
    /** convert(), its LUT files counted as the scene's (content_hash) or not (a header's
     *  chromaticities, measured on one MPI rank only). */
    void convert_noting(const std::string& from, const std::string& to, float* rgb,
                        std::size_t count, bool of_scene) const;
    std::unique_ptr<Impl> impl_;
};

}  // namespace spangle
