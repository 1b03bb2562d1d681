#pragma once
// Component pools in structure-of-arrays form.
//
// A component is declared once with SPANGLE_COMPONENT(Name, FIELDS), where FIELDS is an X-macro
// listing (type, name, doc) triples (the doc string is the field's documentation; a type with a
// comma needs an alias). The macro generates the plain struct Name (one element) and
// Name::Columns (one std::vector per field). Pool<Name> keeps a paged sparse index entity -> dense
// slot, the dense entity array and the columns; removal is swap-and-pop, so iteration order is
// unspecified and changes when entities are removed.

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/check.h"
#include "ecs/entity.h"

#define SPANGLE_DETAIL_FIELD_DECL(type, name, doc) type name{};
#define SPANGLE_DETAIL_COLUMN_DECL(type, name, doc) std::vector<type> name;
#define SPANGLE_DETAIL_COLUMN_PUSH(type, name, doc) name.push_back(v.name);
#define SPANGLE_DETAIL_COLUMN_MOVE(type, name, doc) name[to] = std::move(name[from]);
#define SPANGLE_DETAIL_COLUMN_POP(type, name, doc) name.pop_back();
#define SPANGLE_DETAIL_COLUMN_GET(type, name, doc) r.name = name[i];
#define SPANGLE_DETAIL_COLUMN_SET(type, name, doc) name[i] = v.name;
#define SPANGLE_DETAIL_COLUMN_CLEAR(type, name, doc) name.clear();
#define SPANGLE_DETAIL_FIELD_SAME(type, name, doc) &&::spangle::ecs::same_value(a.name, b.name)

namespace spangle::ecs {
/** Whether two field values count as the same scene content (hot reload's diff). Where a value
 *  is written in the file (FileLoc) does not count: moving a table down a line changes nothing. */
template <class T>
bool same_value(const T& a, const T& b) {
    return a == b;
}
}  // namespace spangle::ecs

/** Declares component Name with SoA columns from FIELDS(X) = X(type, name, doc) .... */
#define SPANGLE_COMPONENT(Name, FIELDS)                                                        \
    struct Name {                                                                              \
        FIELDS(SPANGLE_DETAIL_FIELD_DECL)                                                      \
        static constexpr const char* kName = #Name;                                            \
        struct Columns {                                                                       \
            FIELDS(SPANGLE_DETAIL_COLUMN_DECL)                                                 \
            void push(const Name& v) { FIELDS(SPANGLE_DETAIL_COLUMN_PUSH) }                    \
            void move(std::size_t from, std::size_t to) { FIELDS(SPANGLE_DETAIL_COLUMN_MOVE) } \
            void pop() { FIELDS(SPANGLE_DETAIL_COLUMN_POP) }                                   \
            void clear(){FIELDS(SPANGLE_DETAIL_COLUMN_CLEAR)} Name get(std::size_t i) const {  \
                Name r;                                                                        \
                FIELDS(SPANGLE_DETAIL_COLUMN_GET)                                              \
                return r;                                                                      \
            }                                                                                  \
            void set(std::size_t i, const Name& v) { FIELDS(SPANGLE_DETAIL_COLUMN_SET) }       \
        };                                                                                     \
        static bool same(const Name& a, const Name& b) {                                       \
            return true FIELDS(SPANGLE_DETAIL_FIELD_SAME);                                     \
        }                                                                                      \
    }

namespace spangle::ecs {

/** Type-erased base so the registry can remove an entity from every pool. */
class PoolBase {
public:
    virtual ~PoolBase() = default;
    /** Removes e's component if present; returns whether it was. */
    virtual bool remove(Entity e) = 0;
    /** Number of entities with this component. */
    virtual std::size_t size() const = 0;
    /** The component's name, for --stats and errors. */
    virtual const char* name() const = 0;
    /** Same entities, in the same order, with the same values (see same_value). `other` must
     *  be a pool of the same component type. */
    virtual bool same_as(const PoolBase& other) const = 0;
    /** The entities that have the component, in dense order. */
    virtual std::vector<Entity> entity_list() const = 0;
    /** A new empty pool of the same component type. */
    virtual std::unique_ptr<PoolBase> empty_like() const = 0;
    /** Puts e's component from `other` (a pool of the same type) into this pool; false when
     *  `other` has none for e. */
    virtual bool copy_from(const PoolBase& other, Entity e) = 0;
};

/** One component type's storage: sparse index, dense entities, SoA columns. */
template <class C>
class Pool final : public PoolBase {
public:
    using Columns = typename C::Columns;

    /** Adds or overwrites e's component. */
    void put(Entity e, const C& value) {
        uint32_t& slot = sparse_slot(e.index());
        if (slot != kEmpty && dense_[slot] == e) {
            columns_.set(slot, value);
            return;
        }
        slot = static_cast<uint32_t>(dense_.size());
        dense_.push_back(e);
        columns_.push(value);
    }

    bool remove(Entity e) override {
        const uint32_t slot = find(e);
        if (slot == kEmpty) return false;
        const uint32_t last = static_cast<uint32_t>(dense_.size() - 1);
        if (slot != last) {
            dense_[slot] = dense_[last];
            columns_.move(last, slot);
            sparse_slot(dense_[slot].index()) = slot;
        }
        dense_.pop_back();
        columns_.pop();
        sparse_slot(e.index()) = kEmpty;
        return true;
    }

    /** True when e (this exact generation) has the component. */
    bool has(Entity e) const { return find(e) != kEmpty; }
    /** e's component as a value; e must have it. */
    C get(Entity e) const {
        const uint32_t slot = find(e);
        SPANGLE_CHECK(slot != kEmpty, "entity has no such component");
        return columns_.get(slot);
    }
    /** Dense slot of e, or kEmpty. */
    uint32_t find(Entity e) const {
        const uint32_t page = e.index() / kPageSize;
        if (e.is_null() || page >= pages_.size() || !pages_[page]) return kEmpty;
        const uint32_t slot = (*pages_[page])[e.index() % kPageSize];
        return (slot != kEmpty && dense_[slot] == e) ? slot : kEmpty;
    }

    std::size_t size() const override { return dense_.size(); }
    const char* name() const override { return C::kName; }
    bool same_as(const PoolBase& other) const override {
        const auto& o = static_cast<const Pool<C>&>(other);
        if (dense_ != o.dense_) return false;
        for (std::size_t i = 0; i < dense_.size(); ++i)
            if (!C::same(columns_.get(i), o.columns_.get(i))) return false;
        return true;
    }
    std::vector<Entity> entity_list() const override { return dense_; }
    std::unique_ptr<PoolBase> empty_like() const override { return std::make_unique<Pool<C>>(); }
    bool copy_from(const PoolBase& other, Entity e) override {
        const auto& o = static_cast<const Pool<C>&>(other);
        const uint32_t slot = o.find(e);
        if (slot == kEmpty) return false;
        put(e, o.columns_.get(slot));
        return true;
    }
    /** Dense entity array, parallel to every column. */
    const std::vector<Entity>& entities() const { return dense_; }
    /** The SoA columns: columns().field[slot]. Mutating values is fine; resizing is not. */
    Columns& columns() { return columns_; }
    const Columns& columns() const { return columns_; }

    static constexpr uint32_t kEmpty = 0xffffffffu;

private:
    static constexpr uint32_t kPageSize = 1024;
    using Page = std::array<uint32_t, kPageSize>;

    uint32_t& sparse_slot(uint32_t index) {
        const uint32_t page = index / kPageSize;
        if (page >= pages_.size()) pages_.resize(page + 1);
        if (!pages_[page]) {
            pages_[page] = std::make_unique<Page>();
            pages_[page]->fill(kEmpty);
        }
        return (*pages_[page])[index % kPageSize];
    }

    std::vector<std::unique_ptr<Page>> pages_;  ///< paged sparse index: entity index -> slot
    std::vector<Entity> dense_;                 ///< entity of each dense slot
    Columns columns_;                           ///< one vector per field, parallel to dense_
};

}  // namespace spangle::ecs
