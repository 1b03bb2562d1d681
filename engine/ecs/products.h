#pragma once
// Products: the built state that systems hand to one another (loaded meshes, light tables, the
// acceleration structure), one value per type beside the registry's components. A product type
// is a plain struct with `static constexpr const char* kName` (for --stats and reload reports)
// and `static constexpr bool kProduct = true`. Values are immutable once put and shared: a
// reload that skips a system hands the live scene's value on to the next scene as it is.

#include <memory>
#include <type_traits>
#include <typeindex>
#include <unordered_map>

#include "core/check.h"

namespace spangle::ecs {

/** Whether T is a product type (else a component). */
template <class T, class = void>
struct is_product : std::false_type {};
template <class T>
struct is_product<T, std::void_t<decltype(T::kProduct)>> : std::bool_constant<T::kProduct> {};

/** One value per product type, each shared and immutable. */
class Products {
public:
    /** The value of P, or nullptr when no system made one. */
    template <class P>
    const P* find() const {
        auto it = values_.find(std::type_index(typeid(P)));
        return it == values_.end() ? nullptr : static_cast<const P*>(it->second.get());
    }
    /** The value of P; a system that reads P runs after the one that makes it. */
    template <class P>
    const P& get() const {
        const P* p = find<P>();
        SPANGLE_CHECK(p != nullptr, "a system read a product no system made");
        return *p;
    }
    /** The shared value of P (for a system that reuses part of its last value). */
    template <class P>
    std::shared_ptr<const P> shared() const {
        auto it = values_.find(std::type_index(typeid(P)));
        return it == values_.end() ? nullptr : std::static_pointer_cast<const P>(it->second);
    }
    /** Sets P's value. */
    template <class P>
    void put(P value) {
        values_[std::type_index(typeid(P))] = std::make_shared<const P>(std::move(value));
    }
    /** Takes `type`'s value from `from` (nothing when it has none). */
    void take(std::type_index type, const Products& from) {
        auto it = from.values_.find(type);
        if (it != from.values_.end()) values_[type] = it->second;
    }

private:
    std::unordered_map<std::type_index, std::shared_ptr<const void>> values_;
};

}  // namespace spangle::ecs
