// The GLB container (glTF 2.0 spec, "Binary glTF Layout"): a 12-byte header,
// the JSON chunk and an optional BIN chunk. Shared by the export shim (which
// rewrites tinygltf's JSON chunk) and the reader; C++ only.
#ifndef SYLVA_GLB_CHUNKS_HPP
#define SYLVA_GLB_CHUNKS_HPP

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace sy_glb {

// Splits GLB bytes into its JSON and BIN chunks; false on any inconsistency.
inline bool split(const unsigned char *p, size_t size, std::string &json_text, std::vector<unsigned char> &bin)
{
    auto u32 = [p](size_t at) {
        return (uint32_t)p[at] | (uint32_t)p[at + 1] << 8 | (uint32_t)p[at + 2] << 16 | (uint32_t)p[at + 3] << 24;
    };
    if (size < 20 || memcmp(p, "glTF", 4) != 0 || u32(4) != 2 || u32(8) != size) return false;
    size_t at = 12;
    uint32_t len = u32(at), type = u32(at + 4);
    if (type != 0x4E4F534Au || len > size - at - 8) return false;
    json_text.assign((const char *)p + at + 8, len);
    at += 8 + (size_t)len;
    bin.clear();
    if (at + 8 <= size) {
        len = u32(at);
        type = u32(at + 4);
        if (type != 0x004E4942u || len > size - at - 8) return false;
        bin.assign(p + at + 8, p + at + 8 + len);
    }
    return true;
}

inline void put_u32(std::string &out, uint32_t v)
{
    for (int i = 0; i < 4; i++) out.push_back((char)((v >> (8 * i)) & 0xff));
}

inline std::string join(const std::string &json_text, const std::vector<unsigned char> &bin)
{
    std::string js = json_text;
    while (js.size() % 4) js.push_back(' ');
    size_t bin_padded = (bin.size() + 3) & ~(size_t)3;
    std::string out;
    put_u32(out, 0x46546C67u);
    put_u32(out, 2);
    put_u32(out, (uint32_t)(12 + 8 + js.size() + (bin.empty() ? 0 : 8 + bin_padded)));
    put_u32(out, (uint32_t)js.size());
    put_u32(out, 0x4E4F534Au);
    out += js;
    if (!bin.empty()) {
        put_u32(out, (uint32_t)bin_padded);
        put_u32(out, 0x004E4942u);
        out.append((const char *)bin.data(), bin.size());
        out.append(bin_padded - bin.size(), '\0');
    }
    return out;
}

} // namespace sy_glb

#endif
