#include "pipeline/systems.h"

#include "core/files.h"

namespace spangle {

ecs::Schedule<World> build_schedule() {
    ecs::Schedule<World> s;
    s.add(mesh_load_system());
    s.add(subdivide_system());
    s.add(materials_system());
    s.add(area_lights_system());
    s.add(point_lights_system());
    s.add(environment_system());
    s.add(accelerate_system());
    s.add(cut_outs_system());
    s.add(light_selection_system());
    return s;
}

void World::read_file(const char* kind, const std::string& path) {
    files[system][path] = FileRead{kind, file_identity(path)};
}

}  // namespace spangle
