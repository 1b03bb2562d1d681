#pragma once
// Material instances: a plugin model plus a created instance, and the validation of a scene's
// parameters against the model's schema. The host services plugins receive live here too.

#include <memory>
#include <string>
#include <vector>

#include "color/color_config.h"
#include "core/log.h"
#include "scene/components.h"
#include "shading/plugin_loader.h"

namespace spangle {

/** What the host offers plugins (SpangleHost_v2) and the state behind it. Not copyable: the C
 *  table points at this object. */
class HostServices {
public:
    HostServices(const ColorConfig& color, const Logger& log);
    HostServices(const HostServices&) = delete;
    HostServices& operator=(const HostServices&) = delete;

    const SpangleHost_v2* api() const { return &api_; }
    const ColorConfig& color() const { return color_; }
    const Logger& log() const { return log_; }

private:
    const ColorConfig& color_;
    const Logger& log_;
    std::string working_;  ///< keeps api_.working_space alive
    SpangleHost_v2 api_{};
};

/** One created material: owns the plugin instance and keeps its library open. */
class MaterialInstance {
public:
    MaterialInstance(std::shared_ptr<LoadedPlugin> plugin, const SpangleMaterialModel_v2* model,
                     void* instance, std::string name)
        : plugin_(std::move(plugin)), model_(model), instance_(instance), name_(std::move(name)) {}
    ~MaterialInstance() {
        if (instance_) model_->destroy(instance_);
    }
    MaterialInstance(const MaterialInstance&) = delete;
    MaterialInstance& operator=(const MaterialInstance&) = delete;

    const SpangleMaterialModel_v2& model() const { return *model_; }
    const void* instance() const { return instance_; }
    const std::string& name() const { return name_; }
    const LoadedPlugin& plugin() const { return *plugin_; }

private:
    std::shared_ptr<LoadedPlugin> plugin_;  ///< declared first: destroyed after the instance
    const SpangleMaterialModel_v2* model_;
    void* instance_;
    std::string name_;
};

/** A complete parameter set in schema order, with storage for its strings. */
struct ValidatedParams {
    std::vector<SpangleParamValue_v2> values;  ///< one per schema entry
    std::vector<std::string> strings;          ///< backing text for STRING values
    SpangleParams_v2 view() const { return {values.data(), static_cast<uint32_t>(values.size())}; }
};

/** Checks `m.params` against `model`'s schema: unknown names, types, ranges, choices. Colours are
 *  converted to the working space. Throws SpangleError at the offending value's location. */
ValidatedParams validate_params(const SpangleMaterialModel_v2& model, const Material& m,
                                const ColorConfig& color);

/** Opens m's plugin (once), picks the model, validates, and creates the instance. */
std::unique_ptr<MaterialInstance> create_material(PluginLoader& loader, const Material& m,
                                                  const HostServices& host);

/** One line describing a parameter for `spangle plugins`. */
std::string describe_param(const SpangleParamDesc_v2& p);

}  // namespace spangle
