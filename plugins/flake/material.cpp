#include "material.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <new>
#include <vector>

#include "../common/plugin_support.h"
#include "table_cache.h"

namespace spangle::flake {

using namespace spangle::plugin_support;

namespace {

/** Enumerated flakes per shading point, at most (about 3 ms and 2 MB of arena). */
constexpr uint32_t kEnumerateBound = 65536;

Material::Space parse_space(const std::string& s) {
    if (s == "uv") return Material::Space::Uv;
    if (s == "world") return Material::Space::World;
    if (s == "object") return Material::Space::Object;
    return Material::Space::Auto;
}

/** Builds m.second from the flakes2_* parameters: the same parameter set with the second
 *  population's density, roughness, cone and colour in place of the first's, no colour table,
 *  coat or further population, and its own seed stream. */
bool init_second(Material& m, const SpangleParams_v3* p, const SpangleHost_v3* host,
                 std::string& why) {
    m.second_weight = static_cast<float>(param_number(p, "flakes2_weight"));
    if (!(m.second_weight > 0.0f)) return true;
    std::vector<SpangleParamValue_v3> values(p->values, p->values + p->count);
    const auto set = [&](const char* name, const char* from) {
        const SpangleParamValue_v3* src = from ? find_param(p, from) : nullptr;
        for (auto& v : values)
            if (std::strcmp(v.name, name) == 0)
                for (int c = 0; c < 3; ++c) v.number[c] = src ? src->number[c] : 0.0;
    };
    set("density", "flakes2_density");
    set("flake_roughness", "flakes2_roughness");
    set("gamma", "flakes2_gamma");
    set("flake_color", "flakes2_color");
    set("color_table", nullptr);
    set("coat", nullptr);
    set("flakes2_weight", nullptr);
    const SpangleParams_v3 p2{values.data(), p->count};
    m.second = std::make_unique<Material>();
    if (!init_material(*m.second, &p2, host, why)) {
        why = "flakes2: " + why;
        return false;
    }
    m.second->field.seed = mix(m.field.seed, 0x5ec0d);
    return true;
}

}  // namespace

bool init_material(Material& m, const SpangleParams_v3* p, const SpangleHost_v3* host,
                   std::string& why) {
    m.min_flakes = param_number(p, "min_flakes");
    m.max_flakes = param_number(p, "max_flakes");
    if (!(m.min_flakes < m.max_flakes)) {
        why = "min_flakes must be below max_flakes";
        return false;
    }
    for (int c = 0; c < 3; ++c) m.base[c] = static_cast<float>(param_number(p, "base_color", c));
    m.flake_weight = static_cast<float>(param_number(p, "flake_weight"));
    m.transmits = param_string(p, "fresnel") == "dielectric";
    m.density = static_cast<float>(param_number(p, "density"));
    m.space = parse_space(param_string(p, "density_space"));
    m.tree = param_string(p, "algorithm") != "enumerate";
    m.alpha = static_cast<float>(param_number(p, "flake_roughness"));
    const float gamma = static_cast<float>(param_number(p, "gamma")) * mf::kPi / 180.0f;
    m.cone = Cone(gamma);
    m.footprint_scale = static_cast<float>(param_number(p, "footprint_scale"));
    m.shadowing = param_number(p, "shadowing") != 0.0;
    m.field.seed = static_cast<uint64_t>(param_number(p, "seed"));
    m.field.alpha = m.alpha;
    m.field.leaf_size = static_cast<int>(param_number(p, "leaf_size"));
    m.field.max_depth = static_cast<int>(param_number(p, "max_depth"));
    m.field.exact_below = static_cast<int>(param_number(p, "binomial_exact_below"));
    // A cell must be enumerated whenever it is a leaf: its flakes are not split further.
    m.exact_flakes = static_cast<uint32_t>(
        std::max(param_number(p, "exact_flakes"), static_cast<double>(m.field.leaf_size)));
    m.stand_ins = static_cast<uint32_t>(std::clamp(param_number(p, "stand_ins"), 1.0, 1024.0));
    m.sparse_flakes = static_cast<float>(std::clamp(param_number(p, "sparse_flakes"), 0.0, 1e6));
    m.enumerate_cap =
        static_cast<uint32_t>(std::min(4.0 * m.max_flakes + 64.0, double{kEnumerateBound}));
    // Tables come from the persistent cache when an earlier process (or this one) built them.
    const TableCache cache = TableCache::from_environment([host](const std::string& msg) {
        if (host && host->log) host->log(host->context, SPANGLE_LOG_WARNING, msg.c_str());
    });
    m.coat.init(param_number(p, "coat") != 0.0, static_cast<float>(param_number(p, "coat_ior")),
                static_cast<float>(param_number(p, "coat_roughness")), &cache);
    m.coat_floors = std::make_unique<CoatFloors>(m.coat, cache);
    if (!build_fresnel(m.fresnel, p, host, why) || !build_film(m.film, m.fresnel, p, host, why) ||
        !build_colors(m.colors, m.base, p, host, why))
        return false;
    m.smooth.init(m.alpha, gamma, &m.fresnel, &cache);
    // (The lit table only where sparse_share() reads it.)
    m.grid.init(m.alpha, gamma, m.tree && m.sparse_flakes > 0.0f);
    m.cache_share.init(m.alpha);
    m.sparse.init(m.alpha, gamma, m.fresnel, m.shadowing, &cache);
    m.flake_size = param_number(p, "flake_size");
    if (m.flake_size > 0.0) {
        const std::string shape = param_string(p, "flake_shape");
        m.facet = std::make_unique<FacetShape>(shape == "square"  ? FacetKind::Square
                                               : shape == "round" ? FacetKind::Round
                                                                  : FacetKind::Hexagon);
    }
    return init_second(m, p, host, why);
}

namespace {

/** Copies the scratch cache to the arena and fills the closure's lobe; false without memory. */
bool store_cache(const std::vector<CacheEntry>& scratch, SpangleArena_v3* arena, Closure& c) {
    const auto count = static_cast<uint32_t>(scratch.size());
    if (count == 0) return true;
    if (!arena) return false;
    auto* entries =
        static_cast<CacheEntry*>(arena->allocate(arena->context, count * sizeof(CacheEntry), 16));
    auto* cdf = static_cast<float*>(arena->allocate(arena->context, count * sizeof(float), 16));
    if (!entries || !cdf) return false;
    std::memcpy(entries, scratch.data(), count * sizeof(CacheEntry));
    float run = 0.0f, wsum = 0.0f;
    for (uint32_t j = 0; j < count; ++j) {
        run += entries[j].lum;
        cdf[j] = run;
        wsum += entries[j].w;
    }
    c.lobe = DiscreteLobe{entries, cdf, count, wsum, run};
    return true;
}

/** Whether the tree enumerates the footprint's flakes outright: it spans more uv tiles than the
 *  tree's 2 x 2 (a facet's reach widens it: flakes half a tile wide and more) but at most the
 *  enumeration's 64, and those tiles hold at most 4 x `limit` flakes in all (four cells' worth,
 *  the tree's own bound). Those are the very flakes the tree would enumerate cell by cell; past
 *  2 x 2 tiles it gave up and rendered the smooth lobe, in bands along every tile edge. */
bool sparse_tiles(const FieldParams& field, const Footprint& p, uint32_t limit) {
    const uint64_t tiles = tiles_of(p).count();
    return tiles > 4 && tiles <= 64 &&
           static_cast<double>(root_count(field)) * static_cast<double>(tiles) <=
               4.0 * static_cast<double>(limit);
}

/** Whether the tree enumerates the footprint's facets outright: the flakes whose facets may reach
 *  into it (those under its bounding box widened by the facets' reach) are at most 2 x `limit`
 *  on average, half the tree's own bound. Facets wider than the footprint make the cells (whose
 * size follows the reach) far larger than it: counted, a cell's few flakes inside the footprint are
 *  stand-ins, points, where the facets are mirrors larger than the pixel; and cells counted
 *  beside cells enumerated miss or count twice the facets reaching across their border (darker
 *  and lighter squares a facet's width wide). */
bool few_facets(const FieldParams& field, const Footprint& p, uint32_t limit) {
    // Expected at most 2 x limit, against the enumeration's budget of 4 x limit: a footprint
    // that finds more than its budget shows the smooth lobe instead.
    return field.facet && field.flakes_per_tile * (4.0 * p.half_width() * p.half_height()) <=
                              2.0 * static_cast<double>(limit);
}

/** Mixes a footprint's enumerated lobe (the entries [0, end_enumerated)) and its counted one (the
 *  rest, and c.counted's smooth part) as `enumerated` : 1 - `enumerated`, each normalised by its
 *  own W as it would be alone (eval divides every part by the closure's one W: the entries and
 *  the smooth part are rescaled so that each lobe's weight in it is its share). A lobe whose W is
 *  0 (no flake facing wo) is left out. The cover is mixed alike. (The counted flakes' smooth
 *  share, which prepare_flakes reads for the chance that a footprint holds a flake, is scaled
 *  too; that chance is 1 to within e^-40 at the counts of the fade.) */
void mix_lobes(std::vector<CacheEntry>& scratch, std::size_t end_enumerated, float enumerated,
               float cover_enumerated, float cover_counted, Closure& c) {
    double w_enumerated = 0.0, w_counted = 0.0;
    for (std::size_t j = 0; j < end_enumerated; ++j)
        w_enumerated += static_cast<double>(scratch[j].w);
    for (std::size_t j = end_enumerated; j < scratch.size(); ++j)
        w_counted += static_cast<double>(scratch[j].w);
    w_counted += static_cast<double>(c.counted.smooth) * static_cast<double>(c.w_expected);
    if (!(w_counted > 0.0)) {
        scratch.resize(end_enumerated);
        c.counted = CountedFootprint{};
        c.cover = cover_enumerated;
        return;
    }
    if (!(w_enumerated > 0.0)) {
        scratch.erase(scratch.begin(),
                      scratch.begin() + static_cast<std::ptrdiff_t>(end_enumerated));
        c.cover = cover_counted;
        return;
    }
    const double e = static_cast<double>(enumerated);
    const double w = e * w_enumerated + (1.0 - e) * w_counted;
    const auto a = static_cast<float>(e * w / w_enumerated);
    const auto b = static_cast<float>((1.0 - e) * w / w_counted);
    for (std::size_t j = 0; j < scratch.size(); ++j) {
        CacheEntry& x = scratch[j];
        const float s = j < end_enumerated ? a : b;
        for (int ch = 0; ch < 3; ++ch) x.rgb[ch] *= s;
        x.lum *= s;
        x.w *= s;
    }
    c.counted.smooth *= b;
    c.cover = static_cast<float>(e * static_cast<double>(cover_enumerated) +
                                 (1.0 - e) * static_cast<double>(cover_counted));
}

/** The discrete part of a closure: the flakes of footprint p, by the material's algorithm.
 *  Returns false when the footprint is beyond the algorithm's bound (the smooth lobe takes over).
 */
bool prepare_discrete(const Material& m, const FieldView& view, Closure& c, SpangleArena_v3* arena,
                      PointStats& st) {
    thread_local std::vector<CacheEntry> scratch;
    scratch.clear();
    FieldParams field = m.field;
    field.seed = view.seed;
    field.flakes_per_tile = std::min(view.per_tile, 2147483647.0);
    if (m.facet && view.facet_size > 0.0) {
        field.facet = m.facet.get();
        field.facet_size = view.facet_size;
    }
    const Footprint& p = view.footprint;
    float cover = 0.0f;
    // The flakes' entries are made a batch at a time (their normals in vector code); their ids
    // pick colours and films, where those vary.
    field.lazy_normals = true;
    field.flake_ids = m.colors.varies() || m.film.varies();
    EntryBatch batch;
    const auto add = [&](const Flake& f) {
        if (!kept(f.u, f.v, view.keep)) return;
        cover += f.cover;
        // A facet partly inside the footprint reflects as much of it as lies inside.
        // Facets: marked where their centre lies in the footprint (facet_share()).
        batch.add(c.wo, field.alpha, f.s, f.t, m.colors.pick(f.color_u, f.id),
                  &m.film.pick(f.id, m.fresnel), std::min(f.cover, 1.0f), scratch,
                  field.facet != nullptr && inside(p, f.u, f.v));
    };
    const uint32_t limit = m.tree ? exact_limit(m.exact_flakes, m.grid, c.wo.z) : 0;
    // The share of the discrete lobe the enumeration makes: all of it for `enumerate`, and for
    // the tree's footprints over many tiles of few flakes or under few facets; for point flakes
    // lighting their directions sparsely, sparse_share(), the rest counted; none otherwise.
    const float sparse = m.tree && field.facet == nullptr
                             ? sparse_share(m.sparse_flakes, m.grid, c.wo.z, view.lambda(), c.t)
                             : 0.0f;
    const bool whole = !m.tree || sparse_tiles(field, p, limit) || few_facets(field, p, limit);
    float enumerated = whole ? 1.0f : sparse;
    // The enumerated lobe: the entries [0, end_enumerated).
    std::size_t end_enumerated = 0;
    std::size_t found = 0;  // flakes found (the stand-ins not included), for the statistics
    float cover_enumerated = 0.0f;
    if (enumerated > 0.0f) {
        // The enumeration (where flakes light their directions sparsely: at most 4096 of them
        // on average after the view's thinning to keep >= 1 / sqrt(3), so at most sqrt(3) 4096,
        // about 7 100, on average before it, which for_each_flake counts: the budget of four
        // times kSparseEnumerate is never reached).
        bool truncated = false;
        // (limit is at most kSparseExactCap, exact_flakes being at most 4096 too: the sparse
        // budget is the larger.)
        static_assert(kSparseExactCap <= kSparseEnumerate);
        const uint32_t budget = !m.tree         ? m.enumerate_cap
                                : sparse > 0.0f ? static_cast<uint32_t>(4.0 * kSparseEnumerate)
                                                : 4 * limit;
        for_each_flake(field, p, budget, truncated, add);
        if (truncated) return false;
        flush_entries(c.wo, field.alpha, batch, scratch);
        c.centres_in = batch.entered_marked;
        end_enumerated = scratch.size();
        found = end_enumerated;
        cover_enumerated = cover;
        cover = 0.0f;
        // A footprint of few flakes scaled to average to the far look (facets too: tiny ones
        // are the point flakes, and a large one's albedo is its own flake's, weighted as the
        // far look weights them).
        m.sparse.apply(c.wo.z, static_cast<uint32_t>(end_enumerated), scratch.data(),
                       scratch.data() + end_enumerated);
    }
    if (enumerated < 1.0f) {
        gather_cells(field, p, limit, c.counted, add);
        if (c.counted.truncated) {
            // More tiles than the tree handles: the enumeration alone where it has the footprint.
            if (enumerated <= 0.0f) return false;
            c.counted = CountedFootprint{};
            batch.n = 0;
            scratch.resize(end_enumerated);
            enumerated = 1.0f;
            found = end_enumerated;
        }
    }
    if (enumerated < 1.0f) {
        if (view.keep < 1.0f) {
            // The aggregates' counts thinned alike (binomially, monotone in keep).
            CountedFootprint& cf = c.counted;
            uint32_t kept_agg = 0;
            cf.aggregated = 0;
            for (uint32_t a = 0; a < cf.n_agg; ++a) {
                const uint32_t k = binomial(cf.agg[a].count, view.keep,
                                            unit(mix(cf.agg[a].key, 0x7417)), field.exact_below);
                if (k == 0) continue;
                cf.agg[kept_agg] = cf.agg[a];
                cf.agg[kept_agg++].count = k;
                cf.aggregated += k;
            }
            cf.n_agg = kept_agg;
        }
        flush_entries(c.wo, field.alpha, batch, scratch);
        c.centres_in = batch.entered_marked;
        // (In the fade the enumeration has found every flake: the cells' are among them.)
        if (end_enumerated == 0) found = scratch.size();
        // The aggregates' stand-ins join the cache; the rest of their flakes is the smooth lobe.
        if (c.counted.n_agg > 0)
            add_stand_ins(c.counted, field, p, view.keep, m.stand_ins, m.grid, m.colors, m.fresnel,
                          m.film, c.wo, scratch);
        // Scaled to the far look as the enumeration's; the counted cells' flakes that the smooth
        // part carries count as many as enter the cache (cache_share of them).
        const double k =
            static_cast<double>(scratch.size() - end_enumerated) +
            static_cast<double>(c.counted.smooth) * static_cast<double>(m.cache_share.at(c.wo.z));
        m.sparse.apply(c.wo.z, static_cast<uint32_t>(std::min(k, 1e9)),
                       scratch.data() + end_enumerated, scratch.data() + scratch.size());
    }
    // Facets count towards the cover by their shares, the counted cells' by their expectation:
    // where the facets are wider than the footprint the cells are (their size follows the
    // facets' reach), few of their flakes lie inside it, and a count drawn per cell put square
    // blocks of darker or lighter cover on the surface. Point flakes: whether any is held.
    const float cover_counted =
        cover + (field.facet
                     ? static_cast<float>(c.counted.expected * static_cast<double>(view.keep))
                     : static_cast<float>(c.counted.aggregated));
    c.cover = enumerated >= 1.0f ? cover_enumerated : cover_counted;
    if (enumerated > 0.0f && enumerated < 1.0f)
        mix_lobes(scratch, end_enumerated, enumerated, cover_enumerated, cover_counted, c);
    st.cached += found;
    if (!whole && enumerated > 0.0f) ++(enumerated < 1.0f ? st.sparse_faded : st.sparse_enumerated);
    if (!store_cache(scratch, arena, c)) return false;
    st.aggregated += c.counted.aggregated;
    st.aggregates += c.counted.n_agg;
    // W: the cache's weights (stand-ins included) and the expected weight of the aggregated
    // flakes the smooth lobe carries: each part reflects at most its weight.
    c.w_norm = c.lobe.w_sum + c.counted.smooth * c.w_expected;
    // Sampling within the discrete part: the cache by its luminance, the smooth part by its
    // expected one, through the smooth lobe's proposal.
    float fr[3];
    m.fresnel.eval(1.0f, fr);
    float mean[3] = {m.colors.mean[0] * fr[0], m.colors.mean[1] * fr[1], m.colors.mean[2] * fr[2]};
    const float agg_lum = c.counted.smooth * c.w_expected * std::max(1e-3f, luminance(mean));
    const float total = c.lobe.lum_sum + agg_lum;
    c.p_cache = total > 0.0f ? c.lobe.lum_sum / total : 1.0f;
    return true;
}

/** Smoothstep in log lambda between min_flakes and max_flakes: 0 discrete, 1 smooth. */
float blend_weight(const Material& m, double lambda) {
    if (lambda <= m.min_flakes) return 0.0f;
    if (lambda >= m.max_flakes) return 1.0f;
    const double lo = std::log(std::max(m.min_flakes, 1e-9)), hi = std::log(m.max_flakes);
    const double x = std::clamp((std::log(lambda) - lo) / (hi - lo), 0.0, 1.0);
    return static_cast<float>(x * x * (3.0 - 2.0 * x));
}

/** A tile holds at least this many flakes: a sparser layout is tiled 2^j units at a time (see
 *  tile_side). */
constexpr double kMinFlakesPerTile = 4096.0;

/** The side, in the layout's units, of the tiles of a layout of `per_unit` flakes per unit
 *  square: 1, or the power of two that puts at least kMinFlakesPerTile flakes in a tile. The
 *  tree handles footprints of up to 2 x 2 tiles (the enumeration up to 64), so on a model in
 *  millimetres painted with a few flakes per square millimetre every pixel's footprint spanned
 *  dozens of 1 mm tiles: the smooth lobe everywhere, no glint. Layouts of 4096 flakes per unit
 *  square and more (every metre-scale paint) keep their unit tiles, and their flakes. */
double tile_side(double per_unit) {
    double s = 1.0;
    while (per_unit * s * s < kMinFlakesPerTile && s < 0x1p20) s *= 2.0;
    return s;
}

}  // namespace

FieldView field_view(const Material& m, const PointInput& in) {
    FieldView view;
    view.seed = m.field.seed;
    const bool object = m.space == Material::Space::Object ||
                        (m.space == Material::Space::Auto && (in.flags & SPANGLE_SHADING_NO_UV));
    if (!object) {
        const bool world = m.space == Material::Space::World;
        view.per_tile = world ? static_cast<double>(m.density) * static_cast<double>(in.uv_area)
                              : static_cast<double>(m.density);
        // (Not in world space: its flakes per uv square follow the surface's uv scale point by
        // point, and tiles of changing sizes would change the flakes where they change.)
        const double side = world ? 1.0 : tile_side(view.per_tile);
        const double f = 1.0 / side;  // a power of two: exact
        const auto d = [f](float x) { return static_cast<double>(x) * f; };
        view.footprint = make_footprint(d(in.u), d(in.v), d(in.du_dx), d(in.dv_dx), d(in.du_dy),
                                        d(in.dv_dy), m.footprint_scale);
        view.per_tile *= side * side;
        // flake_size is in metres: in uv units by the local uv-to-area scale (none where the uv
        // scale is unknown: point flakes there), then in tiles.
        if (m.facet && in.uv_area > 0.0f && std::isfinite(in.uv_area))
            view.facet_size = m.flake_size / std::sqrt(static_cast<double>(in.uv_area)) * f;
        view.footprint.reach = m.facet ? view.facet_size * m.facet->radius : 0.0;
        return view;
    }
    const float n[3] = {std::fabs(in.n_obj.x), std::fabs(in.n_obj.y), std::fabs(in.n_obj.z)};
    const int k = n[0] >= n[1] && n[0] >= n[2] ? 0 : n[1] >= n[2] ? 1 : 2;
    const float len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    const int a = (k + 1) % 3, b = (k + 2) % 3;
    const float p[3] = {in.p_obj.x, in.p_obj.y, in.p_obj.z};
    const float dx[3] = {in.dpdx_obj.x, in.dpdx_obj.y, in.dpdx_obj.z};
    const float dy[3] = {in.dpdy_obj.x, in.dpdy_obj.y, in.dpdy_obj.z};
    constexpr double kSqrt3 = 1.7320508075688772;
    view.per_tile = static_cast<double>(m.density) * kSqrt3;
    const double side = tile_side(view.per_tile);
    const double f = 1.0 / side;  // a power of two: exact
    const auto d = [f](float x) { return static_cast<double>(x) * f; };
    view.footprint =
        make_footprint(d(p[a]), d(p[b]), d(dx[a]), d(dx[b]), d(dy[a]), d(dy[b]), m.footprint_scale);
    view.per_tile *= side * side;
    view.seed = mix(m.field.seed, 0x0b1ec7 + static_cast<uint64_t>(k));
    view.keep = len > 0.0f && std::isfinite(len)
                    ? std::min(1.0f, len / (static_cast<float>(kSqrt3) * n[k]))
                    : 0.0f;
    if (m.facet) {
        view.facet_size = m.flake_size * f;
        view.footprint.reach = view.facet_size * m.facet->radius;
    }
    return view;
}

namespace {

/** A footprint's facet share (facet_size set): the share of the footprint that is facets, which
 *  hides the base and scales the flake lobe. The facets' shares inside the footprint are
 *  c.cover (the counted cells' by expectation); `found` is the expected count of those that
 *  reflect wo above the horizon (lambda times cache_share), and `any` whether the footprint
 *  holds the centre of one (or counted cells' flakes that reflect). r is a facet's area over
 *  the footprint's.
 *  - Facets as wide as the footprint or wider (r >= 1): each is a mirror where it lies, the
 *    share w c.cover / lambda, its lobe normalised over the facets that reflect (a footprint
 *    inside a facet that reflects wo into the surface is that dark mirror; one across facets
 *    that do and do not shows those that do at the whole share, as the far look spreads the
 *    share of the flakes that do not over those that do).
 *  - Facets much smaller than the footprint (r <= 1/64, an eighth of its width): the point
 *    flakes' rule (prepare_flakes) on the facets' centres: w / P(any) = w / (1 - e^-found)
 *    where it holds one that reflects, the base alone where it holds none. Averaged over
 *    footprints it is w, and the flakes reflect the far look. With the first rule tiny facets
 *    averaged 0.62 / 0.74 / 0.91 of the far look at lambda 0.5 / 1 / 3 (rough flakes at a low
 *    sun): a footprint whose few facets all faced away hid the base and reflected nothing. Two
 *    rules that looked simpler fail: w in / found (in: the covers of those that reflect) is
 *    capped at 1 where few are expected (0.87 at lambda 0.5, cos 0.1), and
 *    w min(in, 1) / (1 - e^-found) is low where many facets straddle the footprint's edge.
 *  - Between, a smoothstep in log r of the two.
 *  (Showing the far look on facets that face away, so that close-ups average to it too, was
 *  tried: they became grey hexagons of the colour table's mean, noisy with the smooth lobe's
 *  samples, where real glitter shows them dark.) */
float facet_share(const Closure& c, double lambda, double found, bool any, double r) {
    constexpr double kStatistical = 1.0 / 64.0, kGeometric = 1.0;
    double beta = 1.0;
    if (!(r >= kGeometric)) {
        // r 0: log -inf, clamped to 0; r NaN: NaN, taken as 0.
        const double x =
            std::clamp(std::log(r / kStatistical) / std::log(kGeometric / kStatistical), 0.0, 1.0);
        beta = std::isnan(x) ? 0.0 : x * x * (3.0 - 2.0 * x);
    }
    const double w = static_cast<double>(c.weight);
    const double stat = any && found > 0.0 ? 1.0 / -std::expm1(-found) : 0.0;
    // A footprint whose facets all face away has no lobe (c.w_norm 0) and reflects nothing.
    const double geometric = static_cast<double>(c.cover) / lambda;
    return static_cast<float>(std::min(1.0, w * ((1.0 - beta) * stat + beta * geometric)));
}

/** The flake part of a closure (c.wo and c.weight set): its expected weight, the blend and the
 *  discrete lobe of the point's footprint in m's field. */
void prepare_flakes(const Material& m, const PointInput& in, Closure& c, SpangleArena_v3* arena,
                    PointStats& st) {
    c.v_o = m.smooth.valid_fraction(c.wo.z);
    // E[w] over D(m)(m.n): (cos_o / G1(wo)) times the share of visible normals that count.
    c.w_expected = c.wo.z * c.v_o / mf::ggx_g1(c.wo, m.alpha, m.alpha);
    double lambda = INFINITY;
    // Where flake_weight is 0 (a mask's empty region) there are no flakes to find; nor on a
    // triangle without usable uvs when the flakes are laid out in uv (the host's stand-in uvs
    // would repeat one triangle's flakes on every triangle): the smooth lobe there, as the
    // host's warning and the README say.
    const bool no_layout = (m.space == Material::Space::Uv || m.space == Material::Space::World) &&
                           (in.flags & SPANGLE_SHADING_NO_UV);
    if ((in.flags & SPANGLE_SHADING_HAS_DIFFERENTIALS) && c.weight > 0.0f && !no_layout) {
        const FieldView view = field_view(m, in);
        lambda = view.lambda();
        c.t = blend_weight(m, lambda);
        // A centre that is not finite (uv NaN or infinite) has no cells: the smooth lobe.
        const bool finite = std::isfinite(view.footprint.cu) && std::isfinite(view.footprint.cv);
        if (c.t < 1.0f && (!finite || !prepare_discrete(m, view, c, arena, st))) {
            ++st.truncated;
            c.t = 1.0f;
        }
        // The footprint's own flake share (c.weight holds the population's nominal share w).
        // Point flakes: a footprint that holds no flake reflecting wo above the horizon shows
        // the base alone, and one that holds any the share w / P(it holds any) =
        // w / (1 - e^-(found)), at most 1, so the share averages to w wherever
        // w <= 1 - e^-found (a footprint of fewer than ~3 flakes reflected (1 - e^-lambda) of
        // the smooth limit when it kept w always). `found` is the expected count of flakes that
        // enter the cache: of the enumerated ones, those reflecting wo above the horizon
        // (cache_share: 1 / (1 + alpha^2) head-on, about 1/2 at grazing); of the counted
        // cells', the share their smooth part carries whole (it always reflects) and the rest,
        // real flakes as stand-ins, at cache_share too. With lambda alone a rough paint's sparse
        // flakes averaged 8% under w head-on and up to half at grazing. Both average to w as the
        // footprint grows, and the smooth lobe keeps w. Facets: facet_share().
        if (c.t < 1.0f && lambda > 0.0) {
            const double counted =
                std::clamp(c.counted.expected * static_cast<double>(view.keep), 0.0, lambda);
            const double share = static_cast<double>(m.cache_share.at(c.wo.z));
            // Of the aggregates drawn, the share the smooth lobe carries (none where a cell
            // holds no more flakes than its stand-ins: they are its flakes).
            const double smooth = c.counted.aggregated > 0
                                      ? std::clamp(static_cast<double>(c.counted.smooth) /
                                                       static_cast<double>(c.counted.aggregated),
                                                   0.0, 1.0)
                                      : 0.0;
            const double counted_in = counted * (smooth + (1.0 - smooth) * share);
            const double found = counted_in + (lambda - counted) * share;
            float local = 0.0f;
            bool smooth_only = false;  // a footprint that holds none shows the far look's share
            if (m.facet && view.facet_size > 0.0) {
                const double r =
                    view.facet_size * view.facet_size * m.facet->area / view.footprint.area();
                const bool any = c.centres_in > 0 || (c.counted.aggregated > 0 && c.w_norm > 0.0f);
                local = facet_share(c, lambda, found, any, r);
            } else if (c.cover > 0.0f && c.w_norm > 0.0f) {  // holds a flake that wo sees
                local = std::min(
                    1.0f, static_cast<float>(static_cast<double>(c.weight) / -std::expm1(-found)));
            } else if (const double any = -std::expm1(-found);
                       static_cast<double>(c.weight) > any && any < 1.0) {
                // Holds none, where flakes cover more than their chance of lying in a footprint
                // (w > 1 - e^-found: sparse point flakes meant to be larger than a pixel): those
                // that hold one are all flake, and the rest of w (w - P) / (1 - P) is spread over
                // the footprints that hold none, as the far look (their lobe the smooth one), so
                // the share averages to w still. It averaged P: a closer camera or a higher
                // resolution showed more base (the snowman's snowfield, whose white base outshines
                // its crystals, read 10% brighter in a band where lambda fell five times when
                // footprints at grazing views stopped being widened).
                local = static_cast<float>((static_cast<double>(c.weight) - any) / (1.0 - any));
                smooth_only = true;
            }
            if (local != c.weight) c.weight = (1.0f - c.t) * local + c.t * c.weight;
            if (smooth_only) c.t = 1.0f;
        }
    }
    if (std::isfinite(lambda)) {
        st.lambda_milli += static_cast<uint64_t>(std::min(lambda, 1e12) * 1000.0);
        ++st.lambda_count;
    }
    ++(c.t <= 0.0f ? st.discrete : c.t >= 1.0f ? st.smooth : st.blended);
}

/** The luminance a population's flakes reflect at normal incidence (floored: every lobe is
 *  sampled), the weight that steers sampling between lobes. */
float flake_luminance(const Material& m) {
    return std::max(0.05f, luminance(m.colors.mean) * m.fresnel.normal_luminance());
}

/** The second population's closure for the same point, in the arena (the statistics count the
 *  first population only); null when the arena is full (the first population alone). */
Closure* new_second(SpangleArena_v3* arena) {
    if (!arena) return nullptr;
    void* mem = arena->allocate(arena->context, sizeof(Closure), alignof(Closure));
    return mem ? new (mem) Closure{} : nullptr;
}

/** Prepares the second population into c2 (flake_weight w at the point; c prepared with its
 *  share w (1 - flakes2_weight)) and mixes the two: each footprint shows each population's own
 *  share (prepare_flakes), scaled down together where they add up to more than the surface. */
void prepare_second(const Material& m, const PointInput& in, float w, Closure& c, Closure& c2,
                    SpangleArena_v3* arena) {
    c2.wo = c.wo;
    c2.valid = c.valid;
    // The populations' nominal shares (c.weight is the first one's own share by now: it was
    // compared with itself, so a nominal second population reset a sparse first one to nominal,
    // losing its empty footprints' base and its raise: 0.76 of the far look at lambda 0.6).
    const float p1 = w * (1.0f - m.second_weight);
    const float p2 = w * m.second_weight;
    c2.weight = p2;
    PointStats ignored;
    prepare_flakes(*m.second, in, c2, arena, ignored);
    c.second = &c2;
    if (c.weight == p1 && c2.weight == p2) {
        // Both as nominal (the smooth lobe, or footprints of many flakes).
        c.weight = w;
        c.w_second = m.second_weight;
    } else {
        const float sum = c.weight + c2.weight;
        c.weight = std::min(1.0f, sum);
        c.w_second = sum > 0.0f ? c2.weight / sum : m.second_weight;
    }
    const float l1 = (1.0f - c.w_second) * flake_luminance(m);
    const float l2 = c.w_second * flake_luminance(*m.second);
    c.q_second = l2 / (l1 + l2);
}

}  // namespace

namespace {

/** 1 - F of a population's flakes at cos_theta where they are dielectric, else 0. */
void flake_transmission(const Material& m, float cos_theta, float out[3]) {
    out[0] = out[1] = out[2] = 0.0f;
    if (!m.transmits) return;
    m.fresnel.eval(cos_theta, out);
    for (int ch = 0; ch < 3; ++ch) out[ch] = 1.0f - out[ch];
}

/** The share of the base that reaches wo from wi: between the flakes (1 - flake share), and
 *  through dielectric flakes, in and out of one (share times (1 - F_in) (1 - F_out), at the
 *  macro-surface's angles: the flakes' mean normal). Within a flake's area what it reflects (at
 *  most F) and what passes to the base and back (at most (1 - F) times the base's albedo) sum to
 *  at most what arrives. Conductor flakes pass nothing: 1 - share, as before. */
void base_seen(const Material& m, const Closure& c, float cos_i, float out[3]) {
    for (int ch = 0; ch < 3; ++ch) out[ch] = 1.0f - c.weight;
    if (!m.transmits || !(c.weight > 0.0f)) return;
    float ti[3], to[3];
    flake_transmission(m, cos_i, ti);
    flake_transmission(m, c.wo.z, to);
    if (c.second) {
        // The populations' shares of the flakes (they share one Fresnel; each may be absent).
        float t2i[3], t2o[3];
        flake_transmission(*m.second, cos_i, t2i);
        flake_transmission(*m.second, c.wo.z, t2o);
        for (int ch = 0; ch < 3; ++ch) {
            ti[ch] = (1.0f - c.w_second) * ti[ch] * to[ch] + c.w_second * t2i[ch] * t2o[ch];
            to[ch] = 1.0f;
        }
    }
    for (int ch = 0; ch < 3; ++ch) out[ch] += c.weight * ti[ch] * to[ch];
}

}  // namespace

void prepare_point(const Material& m, const PointInput& in, Closure& c, SpangleArena_v3* arena,
                   PointStats& st) {
    c = Closure{};
    c.wo = in.wo;
    std::copy(in.base, in.base + 3, c.base);
    c.weight = in.weight;
    // Path regularisation: the coat, sharp or rough, no sharper than the host's floor (the
    // material's own coat without one). The flakes keep their lobe: after a rough bounce a
    // footprint has no differentials, so it is the smooth lobe already, of the flakes' own width.
    c.coat = &m.coat_floors->at(in.roughness_floor);
    c.valid = c.wo.z > 0.0f ? 1u : 0u;
    if (!c.valid) return;
    c.e_coat_o = c.coat->albedo_at(c.wo.z);
    Closure* c2 = m.second ? new_second(arena) : nullptr;
    if (c2) c.weight = in.weight * (1.0f - m.second_weight);
    prepare_flakes(m, in, c, arena, st);
    if (c2) prepare_second(m, in, in.weight, c, *c2, arena);
    // Lobe selection in proportion to the energy each returns, a sharp coat weighed up (it
    // alone sees a small bright light in it: mf::sharp_lobe_weight).
    const float under = 1.0f - c.e_coat_o;
    const float w_coat =
        c.coat->on ? c.e_coat_o * mf::sharp_lobe_weight(c.coat->roughness()) : 0.0f;
    // The base's share as seen at wo (at wi = wo for the way in: a guess for sampling alone).
    float seen[3];
    base_seen(m, c, c.wo.z, seen);
    const float w_base = under * (m.transmits ? luminance(seen) : 1.0f - c.weight) *
                         luminance(c.base) * c.coat->base_gain();
    const float w_flake = under * c.weight *
                          (c.second ? (1.0f - c.w_second) * flake_luminance(m) +
                                          c.w_second * flake_luminance(*m.second)
                                    : flake_luminance(m));
    const float total = w_coat + w_base + w_flake;
    if (total > 0.0f) {
        c.p_coat = w_coat / total;
        c.p_base = w_base / total;
        c.p_flake = w_flake / total;
    }
}

namespace {

/** The flake lobe at wi (RGB, before flake_weight) and its pdf; `disc` gets the discrete
 *  flakes' part of f. */
void eval_flakes(const Material& m, const Closure& c, V3 wi, float f[3], float& pdf,
                 float disc[3]) {
    f[0] = f[1] = f[2] = pdf = 0.0f;
    disc[0] = disc[1] = disc[2] = 0.0f;
    const float g1_wi = m.shadowing ? mf::ggx_g1(wi, m.alpha, m.alpha) : 1.0f;
    const bool has_agg = c.t < 1.0f && c.counted.smooth > 0.0f;
    const bool need_smooth = c.t > 0.0f || has_agg;
    float fs[3] = {0, 0, 0}, pdf_s = 0.0f;
    if (need_smooth) eval_smooth(m.smooth, c.wo, c.v_o, wi, fs, pdf_s);
    const float* mean = m.colors.mean;
    if (c.t > 0.0f) {
        for (int ch = 0; ch < 3; ++ch) f[ch] += c.t * g1_wi * mean[ch] * fs[ch];
        pdf += c.t * pdf_s;
    }
    if (c.t >= 1.0f || !(c.w_norm > 0.0f)) return;
    float sum[3] = {0, 0, 0}, lum = 0.0f;
    if (c.lobe.count > 0) cone_sums(c.lobe, m.cone, wi, sum, lum);
    // The aggregated flakes the smooth lobe carries, of the expected weight and mean colour.
    const float agg = has_agg ? c.counted.smooth * c.w_expected : 0.0f;
    const float per_cone = 1.0f / (m.cone.solid_angle * wi.z);
    for (int ch = 0; ch < 3; ++ch) sum[ch] = sum[ch] * per_cone + agg * mean[ch] * fs[ch];
    const float k = (1.0f - c.t) * g1_wi / c.w_norm;
    for (int ch = 0; ch < 3; ++ch) {
        disc[ch] = k * sum[ch];
        f[ch] += disc[ch];
    }
    // The smooth part samples the smooth lobe's proposal.
    float pdf_d = 0.0f;
    if (c.p_cache < 1.0f && has_agg) pdf_d = (1.0f - c.p_cache) * pdf_s;
    if (c.p_cache > 0.0f && c.lobe.lum_sum > 0.0f)
        pdf_d += c.p_cache * lum / (c.lobe.lum_sum * m.cone.solid_angle);
    pdf += (1.0f - c.t) * pdf_d;
}

}  // namespace

void eval_material(const Material& m, const Closure& c, V3 wi, float f[3], float& pdf,
                   float* glint) {
    f[0] = f[1] = f[2] = 0.0f;
    pdf = 0.0f;
    if (glint) glint[0] = glint[1] = glint[2] = 0.0f;
    if (!c.valid || wi.z <= 0.0f) return;
    float f_coat = 0.0f, pdf_coat = 0.0f, under = 1.0f;
    const Coat& coat = *c.coat;
    if (coat.on) {
        under = (1.0f - c.e_coat_o) * (1.0f - coat.albedo_at(wi.z));
        if (!coat.smooth) coat.eval_rough(c.wo, wi, f_coat, pdf_coat);
    }
    float fl[3], pdf_fl, disc[3];
    eval_flakes(m, c, wi, fl, pdf_fl, disc);
    if (c.second) {
        // Two populations: their lobes mixed by their shares (a convex sum: no energy gained).
        float f2[3], pdf2, disc2[3];
        eval_flakes(*m.second, *c.second, wi, f2, pdf2, disc2);
        for (int ch = 0; ch < 3; ++ch) {
            fl[ch] = (1.0f - c.w_second) * fl[ch] + c.w_second * f2[ch];
            disc[ch] = (1.0f - c.w_second) * disc[ch] + c.w_second * disc2[ch];
        }
        pdf_fl = (1.0f - c.q_second) * pdf_fl + c.q_second * pdf2;
    }
    // The diffuse base with the bounces between it and the coat (coat.h), the flakes without:
    // seen between the flakes, and through dielectric ones.
    if (!m.transmits) {
        const float base = (1.0f - c.weight) * mf::kInvPi * coat.base_gain();
        for (int ch = 0; ch < 3; ++ch)
            f[ch] = f_coat + under * (base * c.base[ch] + c.weight * fl[ch]);
    } else {
        float seen[3];
        base_seen(m, c, wi.z, seen);
        const float base = mf::kInvPi * coat.base_gain();
        for (int ch = 0; ch < 3; ++ch)
            f[ch] = f_coat + under * (base * seen[ch] * c.base[ch] + c.weight * fl[ch]);
    }
    pdf = c.p_coat * pdf_coat + c.p_base * wi.z * mf::kInvPi + c.p_flake * pdf_fl;
    if (!std::isfinite(f[0] + f[1] + f[2]) || !std::isfinite(pdf)) {
        f[0] = f[1] = f[2] = pdf = 0.0f;
        return;
    }
    if (glint)
        for (int ch = 0; ch < 3; ++ch) glint[ch] = std::min(f[ch], under * c.weight * disc[ch]);
}

namespace {

/** Picks `choice` < p and rescales u to a fresh uniform in [0, 1). */
bool pick(float& u, float p) {
    if (u < p) {
        u = std::min(u / p, 0x1.fffffep-1f);
        return true;
    }
    u = std::min((u - p) / std::max(1e-12f, 1.0f - p), 0x1.fffffep-1f);
    return false;
}

/** Samples the flake lobe of one population (the smooth lobe, the cache or an aggregate, u
 *  choosing); false when it fails. */
bool sample_flakes(const Material& m, const Closure& c, float u, float u0, float u1, V3& wi) {
    bool ok = true;
    if (pick(u, c.t)) {
        ok = sample_smooth(m.smooth, c.wo, u0, u1, wi);
    } else if (pick(u, c.p_cache)) {
        ok = sample_discrete(c.lobe, m.cone, u, u0, u1, wi);
    } else {
        // The aggregated flakes the smooth lobe carries.
        ok = c.counted.smooth > 0.0f && sample_smooth(m.smooth, c.wo, u0, u1, wi);
    }
    return ok;
}

}  // namespace

void sample_material(const Material& m, const Closure& c, float u0, float u1, float u2, V3& wi,
                     float f[3], float& pdf, uint32_t& flags, float* glint) {
    f[0] = f[1] = f[2] = pdf = 0.0f;
    if (glint) glint[0] = glint[1] = glint[2] = 0.0f;
    flags = 0;
    wi = {0, 0, 1};
    if (!c.valid) return;
    float u = u2;
    uint32_t kind = SPANGLE_SAMPLE_REFLECTION | SPANGLE_SAMPLE_GLOSSY;
    bool ok = true;
    if (pick(u, c.p_coat)) {
        const Coat& coat = *c.coat;
        if (coat.smooth) {
            const float fr = mf::fresnel_dielectric(c.wo.z, coat.ior);
            wi = {-c.wo.x, -c.wo.y, c.wo.z};
            f[0] = f[1] = f[2] = fr / c.wo.z;
            pdf = c.p_coat;
            flags = SPANGLE_SAMPLE_REFLECTION | SPANGLE_SAMPLE_SPECULAR;
            return;
        }
        ok = coat.sample_rough(c.wo, u0, u1, wi);
    } else if (pick(u, c.p_base / std::max(1e-12f, 1.0f - c.p_coat))) {
        wi = mf::cosine_hemisphere(u0, u1);
        kind = SPANGLE_SAMPLE_REFLECTION | SPANGLE_SAMPLE_DIFFUSE;
    } else {
        const bool two = c.second && pick(u, c.q_second);
        ok = sample_flakes(two ? *m.second : m, two ? *c.second : c, u, u0, u1, wi);
    }
    if (!ok || !(wi.z > 0.0f)) return;
    eval_material(m, c, wi, f, pdf, glint);  // the whole mixture, so MIS sees one density
    if (!(pdf > 0.0f)) {
        f[0] = f[1] = f[2] = pdf = 0.0f;
        if (glint) glint[0] = glint[1] = glint[2] = 0.0f;
        return;
    }
    flags = kind;
}

}  // namespace spangle::flake
