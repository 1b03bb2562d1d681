#include <gtest/gtest.h>

#include <set>

#include "ecs/registry.h"
#include "ecs/schedule.h"

namespace spangle::ecs {
namespace {

#define TEST_POSITION_FIELDS(X) \
    X(float, x, "x")            \
    X(float, y, "y")
SPANGLE_COMPONENT(Position, TEST_POSITION_FIELDS);

#define TEST_TAG_FIELDS(X) X(int, value, "value")
SPANGLE_COMPONENT(Tag, TEST_TAG_FIELDS);

TEST(EntityAllocator, ReusesSlotsWithNewGeneration) {
    EntityAllocator a;
    const Entity e0 = a.create();
    const Entity e1 = a.create();
    EXPECT_NE(e0, e1);
    EXPECT_TRUE(a.destroy(e0));
    EXPECT_FALSE(a.alive(e0));
    EXPECT_FALSE(a.destroy(e0)) << "destroying twice must be refused";
    const Entity e2 = a.create();
    EXPECT_EQ(e2.index(), e0.index()) << "the freed slot is reused";
    EXPECT_EQ(e2.generation(), e0.generation() + 1);
    EXPECT_FALSE(a.alive(e0)) << "the stale id stays dead after its slot is reused";
    EXPECT_TRUE(a.alive(e2));
    EXPECT_EQ(a.live_count(), 2u);
}

TEST(EntityAllocator, NullEntityIsNeverAlive) {
    EntityAllocator a;
    a.create();
    EXPECT_FALSE(a.alive(Entity{}));
}

TEST(Pool, ColumnsAreParallelToEntities) {
    Registry r;
    std::vector<Entity> es;
    for (int i = 0; i < 5; ++i) {
        es.push_back(r.create());
        r.put(es.back(), Position{static_cast<float>(i), static_cast<float>(10 * i)});
    }
    const Pool<Position>& p = r.pool<Position>();
    ASSERT_EQ(p.size(), 5u);
    ASSERT_EQ(p.columns().x.size(), 5u);
    ASSERT_EQ(p.columns().y.size(), 5u);
    for (std::size_t i = 0; i < p.size(); ++i) {
        const Position v = r.get<Position>(p.entities()[i]);
        EXPECT_EQ(p.columns().x[i], v.x);
        EXPECT_EQ(p.columns().y[i], 10.0f * v.x);
    }
}

TEST(Pool, RemoveKeepsOthersDenseAndFindable) {
    Registry r;
    std::vector<Entity> es;
    for (int i = 0; i < 6; ++i) {
        es.push_back(r.create());
        r.put(es.back(), Position{static_cast<float>(i), 0});
    }
    EXPECT_TRUE(r.remove<Position>(es[1]));
    EXPECT_TRUE(r.remove<Position>(es[4]));
    EXPECT_FALSE(r.remove<Position>(es[4]));
    const Pool<Position>& p = r.pool<Position>();
    EXPECT_EQ(p.size(), 4u);
    std::set<float> seen(p.columns().x.begin(), p.columns().x.end());
    EXPECT_EQ(seen, (std::set<float>{0, 2, 3, 5}));
    for (int i : {0, 2, 3, 5})
        EXPECT_EQ(r.get<Position>(es[static_cast<std::size_t>(i)]).x, static_cast<float>(i));
    EXPECT_FALSE(r.has<Position>(es[1]));
}

TEST(Pool, PutOverwritesExisting) {
    Registry r;
    const Entity e = r.create();
    r.put(e, Tag{1});
    r.put(e, Tag{2});
    EXPECT_EQ(r.count<Tag>(), 1u);
    EXPECT_EQ(r.get<Tag>(e).value, 2);
}

TEST(Registry, DestroyRemovesFromEveryPoolAndStaleIdsMiss) {
    Registry r;
    const Entity a = r.create();
    const Entity b = r.create();
    r.put(a, Tag{1});
    r.put(a, Position{1, 1});
    r.put(b, Tag{2});
    EXPECT_TRUE(r.destroy(a));
    EXPECT_EQ(r.count<Tag>(), 1u);
    EXPECT_EQ(r.count<Position>(), 0u);
    const Entity c = r.create();  // reuses a's slot
    EXPECT_EQ(c.index(), a.index());
    EXPECT_FALSE(r.has<Tag>(a));
    EXPECT_FALSE(r.has<Tag>(c)) << "a new entity in a reused slot has no leftover components";
    EXPECT_EQ(r.get<Tag>(b).value, 2);
}

TEST(Registry, ManyEntitiesAcrossSparsePages) {
    Registry r;
    std::vector<Entity> es;
    for (int i = 0; i < 5000; ++i) es.push_back(r.create());
    for (std::size_t i = 0; i < es.size(); i += 7) r.put(es[i], Tag{static_cast<int>(i)});
    std::size_t n = 0;
    for (std::size_t i = 0; i < es.size(); ++i) {
        ASSERT_EQ(r.has<Tag>(es[i]), i % 7 == 0);
        if (i % 7 == 0) {
            EXPECT_EQ(r.get<Tag>(es[i]).value, static_cast<int>(i));
            ++n;
        }
    }
    EXPECT_EQ(r.count<Tag>(), n);
}

struct Counter {
    int position_runs = 0;
    int tag_runs = 0;
    int either_runs = 0;
};

TEST(Schedule, SkipsSystemsWhoseInputsAreEmpty) {
    Schedule<Counter> s;
    s.add<Position>("positions", RunWhen::AllPresent,
                    [](Registry&, Counter& c) { ++c.position_runs; });
    s.add<Tag, Position>("both", RunWhen::AllPresent, [](Registry&, Counter& c) { ++c.tag_runs; });
    s.add<Tag, Position>("either", RunWhen::AnyPresent,
                         [](Registry&, Counter& c) { ++c.either_runs; });
    Registry r;
    Counter c;
    auto rep = s.run(r, c);
    EXPECT_EQ(c.position_runs + c.tag_runs + c.either_runs, 0);
    ASSERT_EQ(rep.size(), 3u);
    EXPECT_FALSE(rep[0].ran);
    EXPECT_EQ(rep[0].reason, "no Position");
    EXPECT_EQ(rep[1].reason, "no Tag, Position");

    r.put(r.create(), Tag{1});
    rep = s.run(r, c);
    EXPECT_EQ(c.position_runs, 0);
    EXPECT_EQ(c.tag_runs, 0) << "AllPresent needs every input";
    EXPECT_EQ(c.either_runs, 1) << "AnyPresent needs one input";
    EXPECT_EQ(rep[1].reason, "no Position");

    r.put(r.create(), Position{0, 0});
    rep = s.run(r, c);
    EXPECT_EQ(c.position_runs, 1);
    EXPECT_EQ(c.tag_runs, 1);
    EXPECT_TRUE(rep[1].ran);
}

TEST(Schedule, EmptyPoolAfterRemovalSkipsAgain) {
    Schedule<Counter> s;
    s.add<Tag>("tags", RunWhen::AllPresent, [](Registry&, Counter& c) { ++c.tag_runs; });
    Registry r;
    Counter c;
    const Entity e = r.create();
    r.put(e, Tag{1});
    s.run(r, c);
    r.remove<Tag>(e);
    const auto rep = s.run(r, c);
    EXPECT_EQ(c.tag_runs, 1);
    EXPECT_FALSE(rep[0].ran);
}

struct Built {
    static constexpr const char* kName = "Built";
    static constexpr bool kProduct = true;
    int value = 0;
};

bool has_tag(const Registry& r) {
    return r.count<Tag>() > 0;
}

TEST(Schedule, ADeclaredSystemIsAffectedByWhatItReads) {
    const System<Counter> s = system<Counter>("s", [](Registry&, Counter&) {})
                                  .needs_all<Position>()
                                  .reading<Built>()
                                  .reading_if<Tag>(has_tag)
                                  .writing<Built>();
    ASSERT_EQ(s.needs.size(), 1u);
    EXPECT_FALSE(s.needs[0].product);
    ASSERT_EQ(s.writes.size(), 1u);
    EXPECT_TRUE(s.writes[0].product);
    Registry r;
    const auto changed = [](auto... types) { return std::set<std::type_index>{types...}; };
    EXPECT_TRUE(s.affected_by(changed(std::type_index(typeid(Position))), r)) << "its needs";
    EXPECT_TRUE(s.affected_by(changed(std::type_index(typeid(Built))), r)) << "a product";
    EXPECT_FALSE(s.affected_by(changed(std::type_index(typeid(Tag))), r))
        << "a conditional read while the condition does not hold";
    r.put(r.create(), Tag{1});
    EXPECT_TRUE(s.affected_by(changed(std::type_index(typeid(Tag))), r));
    EXPECT_FALSE(s.affected_by({}, r));
}

TEST(Registry, CopyComponentHandsOneEntitysValueOver) {
    Registry a, b;
    const Entity e = a.create();
    ASSERT_EQ(b.create(), e);
    a.put(e, Tag{7});
    EXPECT_TRUE(b.copy_component(std::type_index(typeid(Tag)), a, e));
    EXPECT_EQ(b.get<Tag>(e).value, 7);
    EXPECT_TRUE(b.same_pool(std::type_index(typeid(Tag)), a));
    EXPECT_FALSE(b.copy_component(std::type_index(typeid(Position)), a, e)) << "a has none";
    a.put(e, Tag{8});
    EXPECT_FALSE(b.same_pool(std::type_index(typeid(Tag)), a));
}

}  // namespace
}  // namespace spangle::ecs
