#pragma once
// Helpers shared by the tests that read a SceneDescription (the glTF and pbrt readers' tests): its
// notes and its materials' parameters.

#include <string>

#include "scene/scene_description.h"

namespace spangle::test {

/** Whether a note of `d` contains `text`. */
inline bool has_note(const SceneDescription& d, const std::string& text) {
    for (const std::string& n : d.notes)
        if (n.find(text) != std::string::npos) return true;
    return false;
}

/** The parameter `name` of material `m`, or nullptr. */
inline const ParamDesc* param(const MaterialDesc& m, const std::string& name) {
    for (const ParamDesc& p : m.params)
        if (p.name == name) return &p;
    return nullptr;
}

}  // namespace spangle::test
