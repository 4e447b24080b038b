// Thin tinygltf shim: sy_gltf_doc -> tinygltf::Model -> GLB bytes. tinygltf 2.7 serialises neither buffer nor bufferView
// extensions, so EXT_meshopt_compression's JSON is added to the GLB's JSON
// chunk afterwards with nlohmann::json (the JSON library tinygltf itself uses).
#include "gltf_tinygltf.h"

#include "stages/gltf/glb_chunks.hpp"

#include <tiny_gltf.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

extern "C" {
#include "stages/core/fileio.h"
#include "stages/core/json.h"
}

using nlohmann::json;

namespace {

// The shortest decimal that reads back as the same float, so JSON shows 0.8
// rather than 0.800000011920929 for a float factor.
double tidy(float f) { return sy_float_shortest(f); }

tinygltf::Value number(float f) { return tinygltf::Value(tidy(f)); }

tinygltf::Value float_array(const float *v, size_t n, size_t stride = 1, size_t offset = 0, size_t count = 0)
{
    tinygltf::Value::Array a;
    size_t items = count ? count : n;
    a.reserve(items);
    for (size_t i = 0; i < items; i++) a.push_back(number(v[i * stride + offset]));
    return tinygltf::Value(std::move(a));
}

tinygltf::Value from_json(const json &j)
{
    switch (j.type()) {
    case json::value_t::boolean: return tinygltf::Value(j.get<bool>());
    case json::value_t::number_integer:
    case json::value_t::number_unsigned: {
        double d = j.get<double>();
        if (d >= -2147483648.0 && d <= 2147483647.0) return tinygltf::Value(j.get<int>());
        return tinygltf::Value(d);
    }
    case json::value_t::number_float: return tinygltf::Value(j.get<double>());
    case json::value_t::string: return tinygltf::Value(j.get<std::string>());
    case json::value_t::array: {
        tinygltf::Value::Array a;
        for (const auto &e : j) a.push_back(from_json(e));
        return tinygltf::Value(std::move(a));
    }
    case json::value_t::object: {
        tinygltf::Value::Object o;
        for (auto it = j.begin(); it != j.end(); ++it) o[it.key()] = from_json(it.value());
        return tinygltf::Value(std::move(o));
    }
    default: return tinygltf::Value();
    }
}

int tiny_type(int components)
{
    static const int types[] = {TINYGLTF_TYPE_SCALAR, TINYGLTF_TYPE_SCALAR, TINYGLTF_TYPE_VEC2, TINYGLTF_TYPE_VEC3,
                                TINYGLTF_TYPE_VEC4};
    return types[components < 0 || components > 4 ? 0 : components];
}

tinygltf::Value wind_table(const sy_wind_branch *w, size_t n)
{
    tinygltf::Value::Array parent, level, anchor, axis, length, c2, c4, freq, stiff;
    for (size_t i = 0; i < n; i++) {
        parent.push_back(tinygltf::Value((int)w[i].parent));
        level.push_back(tinygltf::Value(w[i].level));
        for (int c = 0; c < 3; c++) {
            anchor.push_back(number(w[i].anchor[c]));
            axis.push_back(number(w[i].axis[c]));
        }
        length.push_back(number(w[i].length));
        c2.push_back(number(w[i].c2));
        c4.push_back(number(w[i].c4));
        freq.push_back(number(w[i].frequency));
        stiff.push_back(number(w[i].stiffness));
    }
    tinygltf::Value::Object o;
    o["version"] = tinygltf::Value(1);
    o["count"] = tinygltf::Value((int)n);
    o["parent"] = tinygltf::Value(std::move(parent));
    o["level"] = tinygltf::Value(std::move(level));
    o["anchor"] = tinygltf::Value(std::move(anchor));
    o["axis"] = tinygltf::Value(std::move(axis));
    o["length"] = tinygltf::Value(std::move(length));
    o["c2"] = tinygltf::Value(std::move(c2));
    o["c4"] = tinygltf::Value(std::move(c4));
    o["frequency"] = tinygltf::Value(std::move(freq));
    o["stiffness"] = tinygltf::Value(std::move(stiff));
    return tinygltf::Value(std::move(o));
}

void add_material(tinygltf::Model &model, const sy_gltf_material &gm)
{
    const sy_material &m = *gm.src;
    tinygltf::Material mat;
    mat.name = m.name;
    auto &pbr = mat.pbrMetallicRoughness;
    pbr.baseColorFactor.clear();
    for (int c = 0; c < 4; c++) pbr.baseColorFactor.push_back(tidy(m.base_color[c]));
    pbr.metallicFactor = tidy(m.metallic);
    pbr.roughnessFactor = tidy(m.roughness);
    pbr.baseColorTexture.index = gm.base_color_texture;
    mat.normalTexture.index = gm.normal_texture;
    static const char *modes[] = {"OPAQUE", "MASK", "BLEND"};
    mat.alphaMode = modes[m.alpha_mode];
    // alphaCutoff is only meaningful (and only valid) in MASK mode.
    mat.alphaCutoff = m.alpha_mode == SY_ALPHA_MASK ? tidy(m.alpha_cutoff) : 0.5;
    mat.doubleSided = m.double_sided != 0;
    if (m.emissive[0] > 0 || m.emissive[1] > 0 || m.emissive[2] > 0) {
        mat.emissiveFactor.clear();
        for (int c = 0; c < 3; c++) mat.emissiveFactor.push_back(tidy(m.emissive[c]));
        // The glow takes the leaf's own colours: the base colour texture.
        mat.emissiveTexture.index = gm.base_color_texture;
    }
    if (m.diffuse_transmission > 0) {
        tinygltf::Value::Object ext;
        ext["diffuseTransmissionFactor"] = number(m.diffuse_transmission);
        ext["diffuseTransmissionColorFactor"] = float_array(m.diffuse_transmission_color, 3);
        if (gm.transmission_texture >= 0) {
            // One RGBA image: A is the factor, RGB the colour (both slots).
            tinygltf::Value::Object info;
            info["index"] = tinygltf::Value(gm.transmission_texture);
            ext["diffuseTransmissionTexture"] = tinygltf::Value(info);
            ext["diffuseTransmissionColorTexture"] = tinygltf::Value(std::move(info));
        }
        mat.extensions["KHR_materials_diffuse_transmission"] = tinygltf::Value(std::move(ext));
    }
    if (gm.thickness_texture >= 0 && gm.volume) {
        tinygltf::Value::Object ext, info;
        ext["thicknessFactor"] = number(m.thickness_factor);
        info["index"] = tinygltf::Value(gm.thickness_texture);
        ext["thicknessTexture"] = tinygltf::Value(std::move(info));
        mat.extensions["KHR_materials_volume"] = tinygltf::Value(std::move(ext));
    }
    if (gm.hl2_texture[0] >= 0 || gm.hl2_texture[1] >= 0 || (gm.thickness_texture >= 0 && !gm.volume)) {
        // docs/leafmaps.md "HL2 maps": the precomputed directional translucency.
        tinygltf::Value::Object ext;
        static const char *keys[2] = {"adaxialTexture", "abaxialTexture"};
        for (int s = 0; s < 2; s++)
            if (gm.hl2_texture[s] >= 0) {
                tinygltf::Value::Object info;
                info["index"] = tinygltf::Value(gm.hl2_texture[s]);
                ext[keys[s]] = tinygltf::Value(std::move(info));
            }
        if (gm.thickness_texture >= 0 && !gm.volume) {
            // KHR_materials_volume's semantics (green channel times the
            // factor, mesh units), kept here because the card is double-sided.
            tinygltf::Value::Object info;
            info["index"] = tinygltf::Value(gm.thickness_texture);
            ext["thicknessTexture"] = tinygltf::Value(std::move(info));
            ext["thicknessFactor"] = number(m.thickness_factor);
        }
        ext["decodeMin"] = number(m.hl2_min);
        ext["decodeMax"] = number(m.hl2_max);
        ext["transmitAdaxial"] = number(m.hl2_transmit[0]);
        ext["transmitAbaxial"] = number(m.hl2_transmit[1]);
        mat.extensions["SYLVA_leaf_translucency"] = tinygltf::Value(std::move(ext));
    }
    model.materials.push_back(std::move(mat));
}

void add_mesh(tinygltf::Model &model, const sy_gltf_mesh &gm)
{
    tinygltf::Primitive prim;
    prim.mode = TINYGLTF_MODE_TRIANGLES;
    prim.indices = gm.indices;
    prim.material = gm.material;
    const std::pair<const char *, int> attrs[] = {{"POSITION", gm.position},
                                                  {"NORMAL", gm.normal},
                                                  {"TANGENT", gm.tangent},
                                                  {"TEXCOORD_0", gm.texcoord},
                                                  {"_WIND_W", gm.wind_w},
                                                  {"_WIND_BRANCH", gm.wind_branch},
                                                  {"_WIND_ANCHOR", gm.wind_anchor},
                                                  {"_WIND_LEVEL_STIFFNESS", gm.wind_level_stiffness}};
    for (const auto &a : attrs)
        if (a.second >= 0) prim.attributes[a.first] = a.second;
    tinygltf::Mesh mesh;
    mesh.name = gm.name;
    mesh.primitives.push_back(std::move(prim));
    model.meshes.push_back(std::move(mesh));
}

void add_node(tinygltf::Model &model, const sy_gltf_doc &doc, const sy_gltf_node &gn)
{
    tinygltf::Node node;
    node.name = gn.name;
    node.mesh = gn.mesh;
    node.children.assign(gn.children, gn.children + gn.n_children);
    if (gn.inst_translation >= 0) {
        tinygltf::Value::Object attrs;
        attrs["TRANSLATION"] = tinygltf::Value(gn.inst_translation);
        attrs["ROTATION"] = tinygltf::Value(gn.inst_rotation);
        attrs["SCALE"] = tinygltf::Value(gn.inst_scale);
        if (gn.inst_wind_w >= 0) attrs["_WIND_W"] = tinygltf::Value(gn.inst_wind_w);
        if (gn.inst_wind_branch >= 0) attrs["_WIND_BRANCH"] = tinygltf::Value(gn.inst_wind_branch);
        if (gn.inst_wind_anchor >= 0) attrs["_WIND_ANCHOR"] = tinygltf::Value(gn.inst_wind_anchor);
        if (gn.inst_wind_level_stiffness >= 0)
            attrs["_WIND_LEVEL_STIFFNESS"] = tinygltf::Value(gn.inst_wind_level_stiffness);
        tinygltf::Value::Object ext;
        ext["attributes"] = tinygltf::Value(std::move(attrs));
        node.extensions["EXT_mesh_gpu_instancing"] = tinygltf::Value(std::move(ext));
    }
    tinygltf::Value::Object extras;
    if (gn.n_lod_ids > 0) {
        tinygltf::Value::Array ids;
        for (int i = 0; i < gn.n_lod_ids; i++) ids.push_back(tinygltf::Value(gn.lod_ids[i]));
        tinygltf::Value::Object ext;
        ext["ids"] = tinygltf::Value(std::move(ids));
        node.extensions["MSFT_lod"] = tinygltf::Value(std::move(ext));
        extras["MSFT_screencoverage"] = float_array(gn.coverage, (size_t)gn.n_lod_ids + 1);
    }
    if (gn.carries_wind && doc.n_wind) extras["sylva_wind"] = wind_table(doc.wind, doc.n_wind);
    if (!extras.empty()) node.extras = tinygltf::Value(std::move(extras));
    model.nodes.push_back(std::move(node));
}

void add_buffers_and_accessors(tinygltf::Model &model, const sy_gltf_doc &doc)
{
    tinygltf::Buffer buffer;
    buffer.data.assign(doc.bin, doc.bin + doc.bin_size);
    model.buffers.push_back(std::move(buffer));
    for (size_t i = 0; i < doc.n_views; i++) {
        const sy_gltf_view &v = doc.views[i];
        tinygltf::BufferView bv;
        bv.buffer = v.buffer;
        bv.byteOffset = v.offset;
        bv.byteLength = v.length;
        bv.byteStride = (size_t)v.stride;
        bv.target = v.target;
        model.bufferViews.push_back(bv);
    }
    for (size_t i = 0; i < doc.n_accessors; i++) {
        const sy_gltf_accessor &a = doc.accessors[i];
        tinygltf::Accessor acc;
        acc.bufferView = a.view;
        acc.byteOffset = 0;
        acc.componentType = a.component_type;
        acc.count = a.count;
        acc.type = tiny_type(a.components);
        if (a.has_bounds) {
            acc.minValues.assign(a.min, a.min + a.components);
            acc.maxValues.assign(a.max, a.max + a.components);
        }
        model.accessors.push_back(std::move(acc));
    }
}

void add_images_textures(tinygltf::Model &model, const sy_gltf_doc &doc)
{
    for (size_t i = 0; i < doc.n_images; i++) {
        tinygltf::Image img;
        img.name = doc.image_names[i];
        img.bufferView = doc.image_views[i];
        img.mimeType = "image/png";
        model.images.push_back(std::move(img));
    }
    // Only the samplers some texture uses, so no object is left unused.
    int remap[2] = {-1, -1};
    for (size_t t = 0; t < doc.n_textures; t++) {
        int s = doc.textures[t].sampler ? 1 : 0;
        if (remap[s] < 0) {
            tinygltf::Sampler sampler;
            sampler.magFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
            sampler.minFilter = TINYGLTF_TEXTURE_FILTER_LINEAR_MIPMAP_LINEAR;
            sampler.wrapS = sampler.wrapT = s ? TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE : TINYGLTF_TEXTURE_WRAP_REPEAT;
            remap[s] = (int)model.samplers.size();
            model.samplers.push_back(sampler);
        }
        tinygltf::Texture tex;
        tex.source = doc.textures[t].image;
        tex.sampler = remap[s];
        model.textures.push_back(tex);
    }
}

// The EXT_meshopt_compression JSON tinygltf cannot write: the placeholder
// fallback buffer and each compressed view's source range.
void add_meshopt_json(json &j, const sy_gltf_doc &doc)
{
    j["buffers"].push_back({{"byteLength", doc.fallback_size},
                            {"extensions", {{"EXT_meshopt_compression", {{"fallback", true}}}}}});
    for (size_t i = 0; i < doc.n_views; i++) {
        const sy_gltf_view &v = doc.views[i];
        if (v.meshopt == SY_MESHOPT_NONE) continue;
        json ext = {{"buffer", 0},
                    {"byteOffset", v.meshopt_offset},
                    {"byteLength", v.meshopt_length},
                    {"byteStride", v.meshopt_stride},
                    {"count", v.meshopt_count},
                    {"mode", v.meshopt == SY_MESHOPT_TRIANGLES ? "TRIANGLES" : "ATTRIBUTES"}};
        j["bufferViews"][i]["extensions"]["EXT_meshopt_compression"] = ext;
    }
}

} // namespace

extern "C" sy_code sy_gltf_write_glb(const sy_gltf_doc *doc, const char *path, unsigned char **out,
                                     size_t *out_size, sy_error *err)
{
    *out = nullptr;
    *out_size = 0;
    try {
        tinygltf::Model model;
        model.asset.version = "2.0";
        model.asset.generator = doc->generator;
        if (doc->extras_json && doc->extras_json[0]) {
            json extras = json::parse(doc->extras_json, nullptr, false);
            if (extras.is_discarded() || !extras.is_object())
                return sy_fail(err, SY_EINPUT, "%s: asset extras are not a JSON object", path);
            model.asset.extras = from_json(extras);
        }
        add_buffers_and_accessors(model, *doc);
        add_images_textures(model, *doc);
        for (size_t i = 0; i < doc->n_materials; i++) add_material(model, doc->materials[i]);
        for (size_t i = 0; i < doc->n_meshes; i++) add_mesh(model, doc->meshes[i]);
        for (size_t i = 0; i < doc->n_nodes; i++) add_node(model, *doc, doc->nodes[i]);
        tinygltf::Scene scene;
        scene.name = doc->asset_name && doc->asset_name[0] ? doc->asset_name : "tree";
        scene.nodes.push_back(doc->scene_root);
        model.scenes.push_back(scene);
        model.defaultScene = 0;
        // Instancing and meshopt change what a loader must do to show the
        // right thing, so they are required; the material and LOD extensions
        // degrade gracefully (plain PBR, LOD0 only).
        if (doc->uses_transmission) model.extensionsUsed.push_back("KHR_materials_diffuse_transmission");
        if (doc->uses_volume) model.extensionsUsed.push_back("KHR_materials_volume");
        if (doc->uses_leaf_translucency) model.extensionsUsed.push_back("SYLVA_leaf_translucency");
        if (doc->uses_lod) model.extensionsUsed.push_back("MSFT_lod");
        if (doc->uses_instancing) {
            model.extensionsUsed.push_back("EXT_mesh_gpu_instancing");
            model.extensionsRequired.push_back("EXT_mesh_gpu_instancing");
        }
        if (doc->uses_meshopt) {
            model.extensionsUsed.push_back("EXT_meshopt_compression");
            model.extensionsRequired.push_back("EXT_meshopt_compression");
        }

        tinygltf::TinyGLTF writer;
        std::ostringstream stream;
        if (!writer.WriteGltfSceneToStream(&model, stream, false, true))
            return sy_fail(err, SY_EINTERNAL, "%s: tinygltf could not serialise the model", path);
        std::string glb = stream.str();
        if (doc->uses_meshopt) {
            std::string json_text;
            std::vector<unsigned char> bin;
            if (!sy_glb::split((const unsigned char *)glb.data(), glb.size(), json_text, bin))
                return sy_fail(err, SY_EINTERNAL, "%s: tinygltf wrote a malformed GLB", path);
            json j = json::parse(json_text);
            add_meshopt_json(j, *doc);
            glb = sy_glb::join(j.dump(), bin);
        }
        unsigned char *bytes = (unsigned char *)malloc(glb.size());
        if (!bytes) return sy_fail(err, SY_EINTERNAL, "%s: out of memory (%zu bytes)", path, glb.size());
        memcpy(bytes, glb.data(), glb.size());
        *out = bytes;
        *out_size = glb.size();
        return SY_OK;
    } catch (const std::exception &e) {
        return sy_fail(err, SY_EINTERNAL, "%s: glTF serialisation failed: %s", path, e.what());
    }
}
