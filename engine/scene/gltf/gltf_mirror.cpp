// Mirrored glTF placements: glTF makes a node whose world matrix has a negative determinant draw
// its triangles' clockwise side as the front (so a mirrored model keeps its outside out), where
// Spangle takes the side a triangle's corners run counter-clockwise around in world space: a
// mirrored mesh is drawn with its winding reversed.

#include <variant>

#include "scene/gltf/gltf_parts.h"

namespace spangle::gltf {
namespace {

/** A copy of `m` with every triangle's winding reversed. */
std::shared_ptr<const TriangleMesh> reversed_winding(const TriangleMesh& m) {
    auto r = std::make_shared<TriangleMesh>(m);
    r->reverse_winding();
    return r;
}

/** A deformation's meshes with their winding reversed (a mirrored skinned or morphed mesh). */
class ReversedDeformation final : public MeshDeformation {
public:
    explicit ReversedDeformation(std::shared_ptr<const MeshDeformation> inner)
        : inner_(std::move(inner)) {
        first = inner_->first;
        last = inner_->last;
    }
    std::shared_ptr<const TriangleMesh> at(double seconds) const override {
        return reversed_winding(*inner_->at(seconds));
    }

private:
    std::shared_ptr<const MeshDeformation> inner_;
};

}  // namespace

bool mirrors(Context& ctx, const Affine& a, const std::vector<Affine>& keys, const FileLoc& at,
             const std::string& what) {
    const auto one = [](const Affine& m) {
        return !flattens(m) && m.determinant_in_double() < 0.0;
    };
    if (keys.empty()) return one(a);
    const bool first = one(keys.front());
    for (const Affine& k : keys)
        if (one(k) != first) {
            ctx.note("mirrored in part", at,
                     fmt::format("{} mirrors in part of its animation only: its faces follow its "
                                 "first key",
                                 what));
            break;
        }
    return first;
}

void face_for(Context& ctx, ObjectDesc& o, bool mirrored_placement,
              std::optional<InlineMeshShape>& mirrored) {
    if (!mirrored_placement) return;
    auto& shape = std::get<InlineMeshShape>(o.shape);
    if (!mirrored) {
        mirrored = shape;
        if (shape.deformation) {
            mirrored->mesh = reversed_winding(*shape.mesh);
            mirrored->deformation = std::make_shared<ReversedDeformation>(shape.deformation);
        } else {
            auto& copy = ctx.reversed[shape.mesh.get()];
            if (!copy) copy = reversed_winding(*shape.mesh);
            mirrored->mesh = copy;
        }
    }
    shape = *mirrored;
}

}  // namespace spangle::gltf
