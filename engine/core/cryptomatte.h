#pragma once
// Cryptomatte ids (the Cryptomatte specification 1.1, Psyop): a name hashes with MurmurHash3's
// 32-bit variant (seed 0) to a 32-bit word whose bits, with the exponent clamped to [1, 254]
// so that it is never a NaN, an infinity or a denormal, are the float written in the id
// channels. The EXR header names each Cryptomatte by a key and lists its names in a manifest.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace spangle {

/** MurmurHash3_x86_32 of the bytes of `text` with `seed` (Appleby's reference algorithm). */
uint32_t murmur3_32(std::string_view text, uint32_t seed = 0);

/** The Cryptomatte id of `name`: its hash's bits as a float, exponent clamped to [1, 254]. */
float cryptomatte_id(std::string_view name);

/** The 8 lower-case hex digits of the bits of id `id`, as the manifest writes them. */
std::string cryptomatte_hex(float id);

/** The header key of the Cryptomatte named `layer` ("CryptoObject"): the first 7 hex digits of
 *  the hash of its name, so that it is the same in every frame and shot. */
std::string cryptomatte_key(std::string_view layer);

/** The manifest: a JSON object from each distinct name to its id's hex digits (names are
 *  escaped as JSON strings; a repeated name is listed once). */
std::string cryptomatte_manifest(const std::vector<std::string>& names);

}  // namespace spangle
