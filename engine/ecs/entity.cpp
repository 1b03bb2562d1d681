#include "ecs/entity.h"

#include "core/error.h"

namespace spangle::ecs {

Entity EntityAllocator::create() {
    uint32_t index;
    if (!free_.empty()) {
        index = free_.back();
        free_.pop_back();
    } else {
        if (generation_.size() > Entity::kIndexMask - 1)
            throw_error("too many entities: at most {} can be alive at once", Entity::kIndexMask);
        index = static_cast<uint32_t>(generation_.size());
        generation_.push_back(0);
    }
    ++live_;
    return Entity::make(index, generation_[index]);
}

bool EntityAllocator::destroy(Entity e) {
    if (!alive(e)) return false;
    const uint32_t index = e.index();
    // Generation wraps after 4096 reuses of one slot; a stale id that old is accepted as a
    // known limit of 12 generation bits.
    generation_[index] = (generation_[index] + 1) & Entity::kGenerationMask;
    free_.push_back(index);
    --live_;
    return true;
}

bool EntityAllocator::alive(Entity e) const {
    return !e.is_null() && e.index() < generation_.size() &&
           generation_[e.index()] == e.generation();
}

}  // namespace spangle::ecs
