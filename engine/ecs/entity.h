#pragma once
// Entities: 32-bit ids made of a 20-bit slot index and a 12-bit generation. A destroyed entity's
// slot is reused with the next generation, so stale ids are detected instead of aliasing.

#include <cstdint>
#include <vector>

namespace spangle::ecs {

/** An entity id. Value-type, trivially copyable; Entity{} is the null entity. */
struct Entity {
    uint32_t id = kNull;  ///< (generation << kIndexBits) | index

    static constexpr uint32_t kIndexBits = 20;
    static constexpr uint32_t kIndexMask = (1u << kIndexBits) - 1u;
    static constexpr uint32_t kGenerationMask = (1u << (32 - kIndexBits)) - 1u;
    static constexpr uint32_t kNull = 0xffffffffu;

    constexpr uint32_t index() const { return id & kIndexMask; }
    constexpr uint32_t generation() const { return id >> kIndexBits; }
    constexpr bool is_null() const { return id == kNull; }
    constexpr bool operator==(const Entity&) const = default;
    static constexpr Entity make(uint32_t index, uint32_t generation) {
        return Entity{(generation << kIndexBits) | index};
    }
};

/** Creates and destroys entity ids; recycles freed slots (LIFO) with a bumped generation. */
class EntityAllocator {
public:
    /** A new live entity. Throws SpangleError when 2^20 entities are alive at once. */
    Entity create();
    /** Frees e's slot; returns false when e is not alive (already destroyed or stale). */
    bool destroy(Entity e);
    /** True when e was created and not destroyed since. */
    bool alive(Entity e) const;
    /** Number of live entities. */
    uint32_t live_count() const { return live_; }

private:
    std::vector<uint32_t> generation_;  ///< current generation of each slot
    std::vector<uint32_t> free_;        ///< freed slots, reused last-in first-out
    uint32_t live_ = 0;                 ///< live entity count
};

}  // namespace spangle::ecs
