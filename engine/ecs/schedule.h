#pragma once
// The schedule: an ordered list of systems. Each system is a free function with a declaration of
// what it needs, reads and writes:
//   needs   components whose presence gates it: a system whose needs have no entity is skipped
//           and never called, so a scene without subdivision surfaces never touches OpenSubdiv,
//           one without area lights never builds a light table;
//   reads   components and products (ecs/products.h) whose change makes it run again on a reload;
//   writes  components it puts on the entities of its needs, and products it makes.
// A reload (pipeline/session.cpp) runs a system when something it reads changed or a file it read
// was edited, and otherwise hands what it wrote over to the next scene: nothing outside these
// declarations says which system depends on what.

#include <chrono>
#include <set>
#include <string>
#include <typeindex>
#include <vector>

#include "ecs/products.h"
#include "ecs/registry.h"

namespace spangle::ecs {

/** Which of a system's needs must be non-empty for it to run. */
enum class RunWhen {
    AllPresent,  ///< every listed component has at least one entity
    AnyPresent   ///< at least one listed component has an entity
};

/** A component or product type that a system names. */
struct Resource {
    std::type_index type;  ///< the C++ type
    const char* name;      ///< its kName, for --stats and reload reports
    bool product;          ///< a product (else a component)
};

/** The resources of types Ts... (components or products). */
template <class... Ts>
std::vector<Resource> resources() {
    return {Resource{std::type_index(typeid(Ts)), Ts::kName, is_product<Ts>::value}...};
}

/** A system and its declaration. Context is whatever the caller passes along. */
template <class Context>
struct System {
    std::string name;                                  ///< shown by --stats and reload reports
    std::vector<Resource> needs;                       ///< components that gate it (see when)
    RunWhen when = RunWhen::AllPresent;                ///< how needs gate the run
    std::vector<Resource> reads;                       ///< a change of any reruns it on reload
    std::vector<Resource> writes;                      ///< components and products it makes
    std::vector<Resource> conditional_reads;           ///< reads while reads_only_if holds
    bool (*reads_only_if)(const Registry&) = nullptr;  ///< the condition of conditional_reads
    void (*run)(Registry&, Context&) = nullptr;        ///< the system itself

    /** Needs every one of Cs (which it reads too). */
    template <class... Cs>
    System& needs_all() {
        return gate<Cs...>(RunWhen::AllPresent);
    }
    /** Needs any one of Cs (which it reads too). */
    template <class... Cs>
    System& needs_any() {
        return gate<Cs...>(RunWhen::AnyPresent);
    }
    /** Also reads Ts (components or products). */
    template <class... Ts>
    System& reading() {
        append(reads, resources<Ts...>());
        return *this;
    }
    /** Reads Ts only while `when(scene)` holds. */
    template <class... Ts>
    System& reading_if(bool (*condition)(const Registry&)) {
        append(conditional_reads, resources<Ts...>());
        reads_only_if = condition;
        return *this;
    }
    /** Writes Ts: components onto the entities of its needs, products. */
    template <class... Ts>
    System& writing() {
        append(writes, resources<Ts...>());
        return *this;
    }

    /** Whether a change of any type in `changed` makes it run again on scene r. */
    bool affected_by(const std::set<std::type_index>& changed, const Registry& r) const {
        for (const Resource& x : reads)
            if (changed.count(x.type)) return true;
        if (reads_only_if && reads_only_if(r))
            for (const Resource& x : conditional_reads)
                if (changed.count(x.type)) return true;
        return false;
    }

private:
    template <class... Cs>
    System& gate(RunWhen w) {
        needs = resources<Cs...>();
        when = w;
        append(reads, needs);
        return *this;
    }
    static void append(std::vector<Resource>& to, const std::vector<Resource>& more) {
        to.insert(to.end(), more.begin(), more.end());
    }
};

/** A system declared by name and function; the rest by its fluent setters. */
template <class Context>
System<Context> system(std::string name, void (*run)(Registry&, Context&)) {
    System<Context> s;
    s.name = std::move(name);
    s.run = run;
    return s;
}

/** What happened to one system in one run of the schedule. */
struct SystemReport {
    std::string name;      ///< system name
    bool ran = false;      ///< false: skipped (its needs were empty, or nothing it reads changed)
    std::string reason;    ///< why it was skipped ("no AreaLight"), empty when it ran
    double seconds = 0.0;  ///< wall time of the run
};

/** Ordered systems; run() executes them in order, skipping those without input. */
template <class Context>
class Schedule {
public:
    /** Adds a declared system. */
    void add(System<Context> s) { systems_.push_back(std::move(s)); }
    /** Adds a system that needs (and reads) Needs... and declares nothing else. */
    template <class... Needs>
    void add(std::string name, RunWhen when, void (*fn)(Registry&, Context&)) {
        System<Context> s = system<Context>(std::move(name), fn);
        if (when == RunWhen::AllPresent)
            s.template needs_all<Needs...>();
        else
            s.template needs_any<Needs...>();
        systems_.push_back(std::move(s));
    }

    /** Whether system s would run on r now; when not, `reason` (if given) says which needs
     *  are missing. */
    static bool should_run(const System<Context>& s, const Registry& r, std::string* reason) {
        bool any = false, all = true;
        std::string missing;
        for (const Resource& x : s.needs) {
            const bool present = r.count(x.type) > 0;
            any = any || present;
            all = all && present;
            if (!present) missing += (missing.empty() ? "" : ", ") + std::string(x.name);
        }
        const bool run = s.needs.empty() || (s.when == RunWhen::AllPresent ? all : any);
        if (!run && reason) *reason = "no " + missing;
        return run;
    }

    /** Runs every system whose needs exist; returns one report per system, in order. */
    std::vector<SystemReport> run(Registry& r, Context& ctx) const {
        std::vector<SystemReport> out;
        for (const auto& s : systems_) {
            SystemReport rep{s.name, false, {}, 0.0};
            if (should_run(s, r, &rep.reason)) {
                const auto t0 = std::chrono::steady_clock::now();
                s.run(r, ctx);
                rep.seconds =
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
                rep.ran = true;
            }
            out.push_back(std::move(rep));
        }
        return out;
    }

    const std::vector<System<Context>>& systems() const { return systems_; }

private:
    std::vector<System<Context>> systems_;
};

}  // namespace spangle::ecs
