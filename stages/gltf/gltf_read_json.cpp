// The glTF reader's JSON side: a GLB's JSON chunk parsed with nlohmann::json
// (the JSON library tinygltf itself uses), values looked up by RFC 6901 JSON
// pointer, and the BIN chunk; plus tinygltf's own loader as a second opinion.
#include "stages/gltf/gltf_read.h"

#include <tiny_gltf.h>

#include <nlohmann/json.hpp>

#include <cstdio>
#include <exception>
#include <iterator>
#include <string>
#include <vector>

#include "stages/gltf/glb_chunks.hpp"

extern "C" {
#include "stages/core/fileio.h"
}

using nlohmann::json;

struct sy_gltf_file {
    json doc;
    std::vector<unsigned char> bin;
};

extern "C" sy_code sy_gltf_open(const char *path, sy_gltf_file **out, sy_error *err)
{
    *out = nullptr;
    sy_buffer buf;
    sy_code rc = sy_read_file(path, &buf, err);
    if (rc) return rc;
    try {
        auto *f = new sy_gltf_file;
        std::string json_text;
        if (!sy_glb::split(buf.data, buf.size, json_text, f->bin)) {
            delete f;
            sy_buffer_free(&buf);
            return sy_fail(err, SY_EINPUT, "%s: not a well-formed GLB file", path);
        }
        sy_buffer_free(&buf);
        f->doc = json::parse(json_text, nullptr, false);
        if (f->doc.is_discarded() || !f->doc.is_object()) {
            delete f;
            return sy_fail(err, SY_EINPUT, "%s: GLB JSON chunk is not a JSON object", path);
        }
        *out = f;
        return SY_OK;
    } catch (const std::exception &e) {
        sy_buffer_free(&buf);
        return sy_fail(err, SY_EINTERNAL, "%s: %s", path, e.what());
    }
}

extern "C" void sy_gltf_close(sy_gltf_file *f) { delete f; }

static const json *lookup(const sy_gltf_file *f, const char *pointer)
{
    try {
        json::json_pointer p(pointer);
        return f->doc.contains(p) ? &f->doc.at(p) : nullptr;
    } catch (const std::exception &) {
        return nullptr;
    }
}

extern "C" int sy_gltf_has(const sy_gltf_file *f, const char *pointer) { return lookup(f, pointer) != nullptr; }

extern "C" double sy_gltf_number(const sy_gltf_file *f, const char *pointer, double fallback)
{
    const json *v = lookup(f, pointer);
    return v && v->is_number() ? v->get<double>() : fallback;
}

extern "C" const char *sy_gltf_string(const sy_gltf_file *f, const char *pointer, char *buf, size_t size)
{
    const json *v = lookup(f, pointer);
    snprintf(buf, size, "%s", v && v->is_string() ? v->get_ref<const std::string &>().c_str() : "");
    return buf;
}

extern "C" int sy_gltf_size(const sy_gltf_file *f, const char *pointer)
{
    const json *v = lookup(f, pointer);
    return v && (v->is_array() || v->is_object()) ? (int)v->size() : -1;
}

extern "C" const char *sy_gltf_key(const sy_gltf_file *f, const char *pointer, int index, char *buf, size_t size)
{
    const json *v = lookup(f, pointer);
    buf[0] = 0;
    if (!v || !v->is_object() || index < 0 || (size_t)index >= v->size()) return buf;
    auto it = v->begin();
    std::advance(it, index);
    snprintf(buf, size, "%s", it.key().c_str());
    return buf;
}

extern "C" const unsigned char *sy_gltf_bin(const sy_gltf_file *f, size_t *size)
{
    *size = f->bin.size();
    return f->bin.data();
}

extern "C" sy_code sy_gltf_tinygltf_check(const char *path, sy_error *err)
{
    tinygltf::TinyGLTF loader;
    tinygltf::Model model;
    std::string error, warning;
    bool ok = false;
    try {
        ok = loader.LoadBinaryFromFile(&model, &error, &warning, path);
    } catch (const std::exception &e) {
        error = e.what();
    }
    if (ok && error.empty()) return SY_OK;
    std::string one = error + warning;
    for (char &ch : one)
        if (ch == '\n' || ch == '\r') ch = ' ';
    return sy_fail(err, SY_EINPUT, "%s: tinygltf: %s", path, one.c_str());
}
