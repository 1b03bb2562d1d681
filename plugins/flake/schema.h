#pragma once
// The flake model's parameters: name, type, default, range, one-line doc. The host validates
// scene values against this table and `spangle plugins` prints it (the plugin README's table is
// generated from that output).

#include <spangle/plugin.h>

namespace spangle::flake {

// clang-format off
inline const SpangleParamDesc_v3 kParams[] = {
    {"base_color", SPANGLE_PARAM_COLOR, {0.05, 0.05, 0.05}, nullptr, 0.0, 1.0, nullptr, "diffuse colour of the paint between the flakes", SPANGLE_PARAM_TEXTURABLE},
    {"flake_weight", SPANGLE_PARAM_FLOAT, {0.6, 0, 0}, nullptr, 0.0, 1.0, nullptr, "fraction of the surface covered by flakes", SPANGLE_PARAM_TEXTURABLE},
    {"density", SPANGLE_PARAM_FLOAT, {200000, 0, 0}, nullptr, 1e-6, 2147483647.0, nullptr, "flakes per unit square of uv (per square metre with density_space = world; per square unit of the object's own coordinates with object)", 0},
    {"density_space", SPANGLE_PARAM_STRING, {0, 0, 0}, "auto", 0, 0, "auto|uv|world|object", "where flakes are laid out: uv, uv scaled to square metres, object-space position (triplanar), or auto: uv where the mesh has usable uvs, object elsewhere", 0},
    {"algorithm", SPANGLE_PARAM_STRING, {0, 0, 0}, "tree", 0, 0, "tree|enumerate", "tree: counts flakes without enumerating them where they are dense (cost independent of flake count there; footprints whose flakes light their directions sparsely are enumerated up to 4096: sparse_flakes); enumerate: the reference reflection cache of every flake", 0},
    {"exact_flakes", SPANGLE_PARAM_INT, {256, 0, 0}, nullptr, 1.0, 4096.0, nullptr, "tree: footprint cells holding at most this many flakes are enumerated exactly, larger ones counted", 0},
    {"stand_ins", SPANGLE_PARAM_INT, {64, 0, 0}, nullptr, 1.0, 1024.0, nullptr, "tree: flakes a footprint shows, on average, for the flakes it counts (more: closer to real flakes where they are dense, as at grazing views, at proportional cost)", 0},
    {"sparse_flakes", SPANGLE_PARAM_FLOAT, {128, 0, 0}, nullptr, 0.0, 1e6, nullptr, "tree: a footprint whose flakes light a typical direction by at most this many (and that holds at most 4096, below the blend band midpoint) is enumerated, so that its glints have the dark gaps between them that real flakes have; from half of either bound up (and from blend weight 0.1 to 1/2) it fades into the count, so glints stay put as a camera dollies (0: never; cheaper, a grey floor under sparse glints)", 0},
    {"flake_roughness", SPANGLE_PARAM_FLOAT, {0.15, 0, 0}, nullptr, 0.001, 1.0, nullptr, "GGX alpha of the distribution of flake normals around the shading normal", 0},
    {"gamma", SPANGLE_PARAM_FLOAT, {3.0, 0, 0}, nullptr, 0.01, 45.0, nullptr, "half-angle in degrees of the cone each flake reflects into (larger: more, dimmer glints)", 0},
    {"footprint_scale", SPANGLE_PARAM_FLOAT, {1.0, 0, 0}, nullptr, 0.01, 100.0, nullptr, "size of the flake footprint in pixels", 0},
    {"leaf_size", SPANGLE_PARAM_INT, {16, 0, 0}, nullptr, 1.0, 1024.0, nullptr, "quad-tree nodes with at most this many flakes are leaves", 0},
    {"max_depth", SPANGLE_PARAM_INT, {12, 0, 0}, nullptr, 10.0, 24.0, nullptr, "deepest quad-tree level (V-Ray's tex_subdivs)", 0},
    {"binomial_exact_below", SPANGLE_PARAM_INT, {128, 0, 0}, nullptr, 0.0, 1000.0, nullptr, "splits of fewer flakes than this are sampled exactly, larger ones by the normal approximation", 0},
    {"min_flakes", SPANGLE_PARAM_FLOAT, {500, 0, 0}, nullptr, 0.0, 1e9, nullptr, "expected flake count below which only the discrete lobe is used", 0},
    {"max_flakes", SPANGLE_PARAM_FLOAT, {2000, 0, 0}, nullptr, 1.0, 1e9, nullptr, "expected flake count above which only the smooth lobe is used", 0},
    {"fresnel", SPANGLE_PARAM_STRING, {0, 0, 0}, "conductor", 0, 0, "conductor|dielectric|schlick", "Fresnel of a flake: a metal (preset), a dielectric (flake_ior) or Schlick (flake_f0)", 0},
    {"preset", SPANGLE_PARAM_STRING, {0, 0, 0}, "aluminium", 0, 0, "gold|silver|copper|aluminium|perfect", "metal of conductor flakes", 0},
    {"flake_ior", SPANGLE_PARAM_FLOAT, {1.5, 0, 0}, nullptr, 1.0, 10.0, nullptr, "index of dielectric flakes", 0},
    {"flake_f0", SPANGLE_PARAM_FLOAT, {0.9, 0, 0}, nullptr, 0.0, 1.0, nullptr, "normal-incidence reflectance of Schlick flakes", 0},
    {"flake_color", SPANGLE_PARAM_COLOR, {1.0, 1.0, 1.0}, nullptr, 0.0, 1.0, nullptr, "tint of every flake when the colour table is off", 0},
    {"shadowing", SPANGLE_PARAM_BOOL, {1, 0, 0}, nullptr, 0, 1, nullptr, "apply Smith shadowing G1(wi) of the flake distribution", 0},
    {"color_table", SPANGLE_PARAM_BOOL, {0, 0, 0}, nullptr, 0, 1, nullptr, "give flakes colours from an HSL hue table instead of flake_color", 0},
    {"table_size", SPANGLE_PARAM_INT, {60, 0, 0}, nullptr, 1.0, 360.0, nullptr, "number of hues in the colour table", 0},
    {"table_s", SPANGLE_PARAM_FLOAT, {1.0, 0, 0}, nullptr, 0.0, 1.0, nullptr, "HSL saturation of the table", 0},
    {"table_l", SPANGLE_PARAM_FLOAT, {0.5, 0, 0}, nullptr, 0.0, 1.0, nullptr, "HSL lightness of the table", 0},
    {"table_space", SPANGLE_PARAM_STRING, {0, 0, 0}, "srgb_texture", 0, 0, nullptr, "colour space the HSL table is defined in (any name of the OCIO config)", 0},
    {"hue_spread", SPANGLE_PARAM_FLOAT, {0, 0, 0}, nullptr, 0.0, 360.0, nullptr, "degrees: flake hues are biased towards base_color's hue with this spread; 0 = uniform", 0},
    {"hue_variation", SPANGLE_PARAM_FLOAT, {0, 0, 0}, nullptr, 0.0, 180.0, nullptr, "degrees: each flake's hue moves by its own offset, uniform in [-hue_variation, hue_variation]; 0 = off", 0},
    {"saturation_variation", SPANGLE_PARAM_FLOAT, {0, 0, 0}, nullptr, 0.0, 1.0, nullptr, "each flake's HSV saturation moves by its own offset, uniform in [-x, x] (greys stay grey); 0 = off", 0},
    {"value_variation", SPANGLE_PARAM_FLOAT, {0, 0, 0}, nullptr, 0.0, 1.0, nullptr, "each flake's HSV value is scaled by its own factor, uniform in [1 - x, 1 + x], at most 1; 0 = off", 0},
    {"film_thickness_min", SPANGLE_PARAM_FLOAT, {0, 0, 0}, nullptr, 0.0, 5000.0, nullptr, "nm: thinnest film on a flake (each flake's thickness is its own, uniform in [min, max])", 0},
    {"film_thickness_max", SPANGLE_PARAM_FLOAT, {0, 0, 0}, nullptr, 0.0, 5000.0, nullptr, "nm: thickest film on a flake; 0 = no film (interference flakes off)", 0},
    {"film_ior", SPANGLE_PARAM_FLOAT, {1.5, 0, 0}, nullptr, 1.0, 4.0, nullptr, "index of the flakes' thin film (TiO2 about 2.4, SiO2 1.46)", 0},
    {"flakes2_weight", SPANGLE_PARAM_FLOAT, {0, 0, 0}, nullptr, 0.0, 1.0, nullptr, "share of the flake lobe taken by a second population of flakes (its own field); 0 = one population", 0},
    {"flakes2_density", SPANGLE_PARAM_FLOAT, {2000, 0, 0}, nullptr, 1e-6, 2147483647.0, nullptr, "second population: flakes per unit square (in density_space, like density)", 0},
    {"flakes2_color", SPANGLE_PARAM_COLOR, {1.0, 0.35, 0.1}, nullptr, 0.0, 1.0, nullptr, "second population: tint of its flakes (varied like the first's)", 0},
    {"flakes2_roughness", SPANGLE_PARAM_FLOAT, {0.3, 0, 0}, nullptr, 0.001, 1.0, nullptr, "second population: GGX alpha of its flake normals", 0},
    {"flakes2_gamma", SPANGLE_PARAM_FLOAT, {3.0, 0, 0}, nullptr, 0.01, 45.0, nullptr, "second population: half-angle in degrees of its flakes' cones", 0},
    {"coat", SPANGLE_PARAM_BOOL, {0, 0, 0}, nullptr, 0, 1, nullptr, "add a clear coat on top", 0},
    {"coat_ior", SPANGLE_PARAM_FLOAT, {1.5, 0, 0}, nullptr, 1.0, 10.0, nullptr, "index of the clear coat", 0},
    {"coat_roughness", SPANGLE_PARAM_FLOAT, {0.0, 0, 0}, nullptr, 0.0, 1.0, nullptr, "GGX alpha of the clear coat; below 1e-4 a smooth coat", 0},
    {"flake_size", SPANGLE_PARAM_FLOAT, {0, 0, 0}, nullptr, 0.0, 1.0, nullptr, "metres: width of a flake's facet (flat mirror with the flake_shape outline, seen where a pixel is not much larger); 0 = point flakes", 0},
    {"flake_shape", SPANGLE_PARAM_STRING, {0, 0, 0}, "hexagon", 0, 0, "hexagon|square|round", "outline of a flake's facet when flake_size > 0 (width flat to flat, side, or diameter)", 0},
    {"seed", SPANGLE_PARAM_INT, {0, 0, 0}, nullptr, 0.0, 2147483647.0, nullptr, "which realisation of flakes: change it for a different but equivalent pattern", 0},
};
// clang-format on
inline constexpr uint32_t kParamCount = sizeof(kParams) / sizeof(kParams[0]);

}  // namespace spangle::flake
