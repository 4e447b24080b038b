// The glTF reader's geometry side (tinygltf shim): the triangle soup of a
// glTF scene in Sylva's world frame (Z up), and the whole scene for drawing it
// (sy_gltf_read_scene: meshes, materials, images, instancing, LODs, wind).
#include "stages/gltf/gltf_read.h"

#include <meshoptimizer.h>
#include <stb_image.h>
#include <tiny_gltf.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <sys/stat.h>

namespace {

using Mat4 = std::array<double, 16>; // column-major, as glTF stores matrices

constexpr size_t kMaxTriangles = size_t(1) << 28; // 2.7e8 triangles, ~19 GB of doubles
constexpr double kMaxCoordinate = 1e9;            // SY_WORLD_MAX (stages/core/cloud.h)

struct Failure {
    int code;
    std::string what;
};

std::string number(double v)
{
    char b[32];
    std::snprintf(b, sizeof b, "%g", v);
    return b;
}

// An accessor index from an extension's JSON: a whole number in int range
// (tinygltf's GetNumberAsInt casts any double, which is undefined past it).
int index_value(const tinygltf::Value &v, const char *what)
{
    double d = v.GetNumberAsDouble();
    if (!(d >= 0 && d <= 2147483647.0) || d != std::floor(d))
        throw Failure{2, std::string(what) + " is not an accessor index"};
    return int(d);
}

Mat4 identity()
{
    Mat4 m{};
    m[0] = m[5] = m[10] = m[15] = 1;
    return m;
}

Mat4 mul(const Mat4 &a, const Mat4 &b)
{
    Mat4 r{};
    for (int c = 0; c < 4; c++)
        for (int row = 0; row < 4; row++) {
            double s = 0;
            for (int k = 0; k < 4; k++) s += a[k * 4 + row] * b[c * 4 + k];
            r[c * 4 + row] = s;
        }
    return r;
}

// T * R * S from translation, unit quaternion (x, y, z, w) and scale.
Mat4 trs(const double t[3], const double q[4], const double s[3])
{
    double x = q[0], y = q[1], z = q[2], w = q[3];
    double n = std::sqrt(x * x + y * y + z * z + w * w);
    if (n > 0) x /= n, y /= n, z /= n, w /= n;
    else x = y = z = 0, w = 1;
    double r[9] = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w),     2 * (x * z - y * w),
                   2 * (x * y - z * w),     1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
                   2 * (x * z + y * w),     2 * (y * z - x * w),     1 - 2 * (x * x + y * y)};
    Mat4 m = identity();
    for (int c = 0; c < 3; c++)
        for (int row = 0; row < 3; row++) m[c * 4 + row] = r[c * 3 + row] * s[c];
    m[12] = t[0], m[13] = t[1], m[14] = t[2];
    return m;
}

Mat4 local_transform(const tinygltf::Node &n)
{
    if (n.matrix.size() == 16) {
        Mat4 m;
        for (int i = 0; i < 16; i++) m[i] = n.matrix[i];
        return m;
    }
    double t[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
    if (n.translation.size() == 3) for (int i = 0; i < 3; i++) t[i] = n.translation[i];
    if (n.rotation.size() == 4) for (int i = 0; i < 4; i++) q[i] = n.rotation[i];
    if (n.scale.size() == 3) for (int i = 0; i < 3; i++) s[i] = n.scale[i];
    return trs(t, q, s);
}

// Reads accessor element i component c as double (normalized integers scaled
// per the glTF rules), with every offset checked against the buffer.
class AccessorView {
  public:
    AccessorView(const tinygltf::Model &m, int index, const char *what)
    {
        if (index < 0 || size_t(index) >= m.accessors.size()) throw Failure{2, std::string(what) + " accessor index out of range"};
        const tinygltf::Accessor &a = m.accessors[size_t(index)];
        if (a.sparse.isSparse) throw Failure{2, std::string(what) + ": sparse accessors are not supported"};
        if (a.bufferView < 0 || size_t(a.bufferView) >= m.bufferViews.size())
            throw Failure{2, std::string(what) + " accessor has no valid bufferView"};
        const tinygltf::BufferView &bv = m.bufferViews[size_t(a.bufferView)];
        if (bv.buffer < 0 || size_t(bv.buffer) >= m.buffers.size()) throw Failure{2, std::string(what) + " bufferView has no valid buffer"};
        const std::vector<unsigned char> &buf = m.buffers[size_t(bv.buffer)].data;
        comps_ = tinygltf::GetNumComponentsInType(uint32_t(a.type));
        size_ = tinygltf::GetComponentSizeInBytes(uint32_t(a.componentType));
        int stride = a.ByteStride(bv);
        if (comps_ <= 0 || size_ <= 0 || stride <= 0) throw Failure{2, std::string(what) + " accessor has an invalid type or stride"};
        count_ = a.count;
        type_ = a.componentType;
        normalized_ = a.normalized;
        stride_ = size_t(stride);
        size_t elem = size_t(comps_) * size_t(size_);
        if (bv.byteOffset > buf.size() || bv.byteLength > buf.size() - bv.byteOffset || a.byteOffset > bv.byteLength)
            throw Failure{2, std::string(what) + " bufferView lies outside its buffer"};
        size_t avail = bv.byteLength - a.byteOffset;
        if (count_ && (elem > avail || (count_ - 1) > (avail - elem) / stride_))
            throw Failure{2, std::string(what) + " accessor reads past its bufferView"};
        base_ = buf.data() + bv.byteOffset + a.byteOffset;
    }
    size_t count() const { return count_; }
    int components() const { return comps_; }
    double get(size_t i, int c) const
    {
        const unsigned char *p = base_ + i * stride_ + size_t(c) * size_t(size_);
        switch (type_) {
        case TINYGLTF_COMPONENT_TYPE_FLOAT: { float f; std::memcpy(&f, p, 4); return f; }
        case TINYGLTF_COMPONENT_TYPE_DOUBLE: { double d; std::memcpy(&d, p, 8); return d; }
        case TINYGLTF_COMPONENT_TYPE_BYTE: { int8_t v; std::memcpy(&v, p, 1); return normalized_ ? std::fmax(v / 127.0, -1.0) : v; }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: { uint8_t v = *p; return normalized_ ? v / 255.0 : v; }
        case TINYGLTF_COMPONENT_TYPE_SHORT: { int16_t v; std::memcpy(&v, p, 2); return normalized_ ? std::fmax(v / 32767.0, -1.0) : v; }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: { uint16_t v; std::memcpy(&v, p, 2); return normalized_ ? v / 65535.0 : v; }
        case TINYGLTF_COMPONENT_TYPE_INT: { int32_t v; std::memcpy(&v, p, 4); return v; }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: { uint32_t v; std::memcpy(&v, p, 4); return v; }
        default: return 0;
        }
    }

  private:
    const unsigned char *base_ = nullptr;
    size_t count_ = 0, stride_ = 0;
    int comps_ = 0, size_ = 0, type_ = 0;
    bool normalized_ = false;
};

// Sylva draws cluster hulls, each closed and facing outward, as one mesh of
// this name (pipeline/tree_asset.c): its connected parts are those hulls.
constexpr const char *kHullMesh = "foliage_proxy";

// Connected part of each index (0-based, in order of first appearance).
std::vector<size_t> components(const std::vector<size_t> &idx, size_t n_vertices)
{
    std::vector<size_t> up(n_vertices);
    for (size_t i = 0; i < n_vertices; i++) up[i] = i;
    auto find = [&up](size_t x) {
        while (up[x] != x) x = up[x] = up[up[x]];
        return x;
    };
    for (size_t t = 0; t + 2 < idx.size(); t += 3)
        for (int k = 1; k < 3; k++) up[find(idx[t + size_t(k)])] = find(idx[t]);
    std::vector<size_t> label(n_vertices, 0), part(idx.size() / 3);
    std::vector<bool> labelled(n_vertices, false);
    size_t next = 0;
    for (size_t t = 0; t + 2 < idx.size(); t += 3) {
        size_t r = find(idx[t]);
        if (!labelled[r]) label[r] = next++, labelled[r] = true;
        part[t / 3] = label[r];
    }
    return part;
}

struct Reader {
    explicit Reader(const tinygltf::Model &model) : m(model) {}
    const tinygltf::Model &m;
    std::vector<double> out;
    std::vector<size_t> hull; // per triangle: 0, or 1 + the closed hull it belongs to
    size_t n_hulls = 0;
    size_t visits = 0;
    // The cut-out (sy_gltf_read_surface): per triangle its corners' uv and alpha map.
    bool want_cut = false;
    std::vector<float> uv;
    std::vector<int32_t> tmap;
    std::vector<sy_gltf_alpha_map> maps;
    std::vector<std::vector<unsigned char>> alphas; // the maps' texels
    std::map<int, int> map_of_material;

    // The alpha map of material mat (-1: its triangles are drawn whole):
    // alphaMode MASK, alpha = baseColorFactor's times the baseColorTexture's
    // (TEXCOORD_0; a texture on another set is not followed), 1 x 1 without one.
    int alpha_map(int mat)
    {
        if (mat < 0 || size_t(mat) >= m.materials.size()) return -1;
        auto found = map_of_material.find(mat);
        if (found != map_of_material.end()) return found->second;
        const tinygltf::Material &mt = m.materials[size_t(mat)];
        const tinygltf::PbrMetallicRoughness &pbr = mt.pbrMetallicRoughness;
        int result = -1;
        if (mt.alphaMode == "MASK") {
            double fa = pbr.baseColorFactor.size() == 4 ? pbr.baseColorFactor[3] : 1.0;
            fa = fa < 0 ? 0 : fa > 1 ? 1 : fa;
            sy_gltf_alpha_map am{1, 1, float(mt.alphaCutoff), nullptr};
            std::vector<unsigned char> px(1, (unsigned char)std::lround(255 * fa));
            int ti = pbr.baseColorTexture.index;
            if (ti >= 0 && size_t(ti) < m.textures.size() && pbr.baseColorTexture.texCoord == 0) {
                int src = m.textures[size_t(ti)].source;
                const tinygltf::Image *im = src >= 0 && size_t(src) < m.images.size() ? &m.images[size_t(src)] : nullptr;
                int comps = im ? im->component : 0, bytes = im && im->bits == 16 ? 2 : 1;
                size_t n = im && im->width > 0 && im->height > 0 ? size_t(im->width) * size_t(im->height) : 0;
                if (n && comps >= 1 && comps <= 4 && im->image.size() >= n * size_t(comps * bytes)) {
                    am.w = im->width, am.h = im->height;
                    px.assign(n, (unsigned char)std::lround(255 * fa));
                    if (comps == 2 || comps == 4)
                        for (size_t i = 0; i < n; i++) {
                            // The high byte of a 16-bit texel (tinygltf keeps them little-endian).
                            unsigned a = im->image[(i * size_t(comps) + size_t(comps - 1)) * size_t(bytes) + size_t(bytes - 1)];
                            px[i] = (unsigned char)std::lround(a * fa);
                        }
                }
            }
            result = int(maps.size());
            maps.push_back(am);
            alphas.push_back(std::move(px));
        }
        map_of_material[mat] = result;
        return result;
    }

    // Instance matrices of EXT_mesh_gpu_instancing, or one identity.
    std::vector<Mat4> instances(const tinygltf::Node &n)
    {
        auto it = n.extensions.find("EXT_mesh_gpu_instancing");
        if (it == n.extensions.end() || !it->second.IsObject() || !it->second.Has("attributes")) return {identity()};
        const tinygltf::Value &attrs = it->second.Get("attributes");
        const char *names[3] = {"TRANSLATION", "ROTATION", "SCALE"};
        const int widths[3] = {3, 4, 3};
        std::vector<AccessorView> views;
        std::vector<int> which;
        size_t count = 0;
        for (int k = 0; k < 3; k++) {
            if (!attrs.Has(names[k])) continue;
            const tinygltf::Value &v = attrs.Get(names[k]);
            if (!v.IsNumber()) throw Failure{2, std::string("EXT_mesh_gpu_instancing ") + names[k] + " is not an accessor index"};
            views.emplace_back(m, index_value(v, (std::string("EXT_mesh_gpu_instancing ") + names[k]).c_str()), "EXT_mesh_gpu_instancing");
            if (views.back().components() != widths[k]) throw Failure{2, std::string("EXT_mesh_gpu_instancing ") + names[k] + " has the wrong type"};
            if (views.size() > 1 && views.back().count() != count) throw Failure{2, "EXT_mesh_gpu_instancing attributes differ in count"};
            count = views.back().count();
            which.push_back(k);
        }
        if (views.empty()) return {identity()};
        std::vector<Mat4> result;
        result.reserve(count);
        for (size_t i = 0; i < count; i++) {
            double t[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
            for (size_t v = 0; v < views.size(); v++) {
                double *dst = which[v] == 0 ? t : which[v] == 1 ? q : s;
                for (int c = 0; c < widths[which[v]]; c++) dst[c] = views[v].get(i, c);
            }
            result.push_back(trs(t, q, s));
        }
        return result;
    }

    void emit(const Mat4 &xf, const AccessorView &pos, size_t a, size_t b, size_t c, size_t hull_id,
              const AccessorView *tc = nullptr, int map = -1)
    {
        if (out.size() / 9 >= kMaxTriangles) throw Failure{2, "more than 2^28 triangles"};
        hull.push_back(hull_id);
        if (want_cut) {
            tmap.push_back(map);
            for (size_t v : {a, b, c})
                for (int k = 0; k < 2; k++) {
                    // A coordinate beyond float (a DOUBLE accessor) is NaN: drawn (sy_gltf_cutout_drawn).
                    double x = tc ? tc->get(v, k) : 0.0;
                    uv.push_back(std::fabs(x) <= FLT_MAX ? float(x) : NAN);
                }
        }
        for (size_t v : {a, b, c}) {
            double p[3] = {pos.get(v, 0), pos.get(v, 1), pos.get(v, 2)}, w[3];
            for (int r = 0; r < 3; r++) {
                w[r] = xf[r] * p[0] + xf[4 + r] * p[1] + xf[8 + r] * p[2] + xf[12 + r];
                // A matrix of 1e308 or a NaN vertex: no tree lies there, and
                // every later sample count would follow the number.
                if (!(std::fabs(w[r]) <= kMaxCoordinate))
                    throw Failure{2, "vertex " + std::to_string(v) + " lies at " + number(w[r]) +
                                         " m after its node transforms (beyond 1e9 m or not finite)"};
            }
            // glTF Y-up to Sylva Z-up.
            out.push_back(w[0]);
            out.push_back(-w[2]);
            out.push_back(w[1]);
        }
    }

    void primitive(const tinygltf::Primitive &prim, const std::vector<Mat4> &xfs, bool hulls)
    {
        int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
        if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN) return;
        auto it = prim.attributes.find("POSITION");
        if (it == prim.attributes.end()) return;
        AccessorView pos(m, it->second, "POSITION");
        if (pos.components() != 3) throw Failure{2, "POSITION is not a VEC3 accessor"};
        std::vector<size_t> idx;
        if (prim.indices >= 0) {
            AccessorView ind(m, prim.indices, "index");
            idx.resize(ind.count());
            for (size_t i = 0; i < ind.count(); i++) {
                double v = ind.get(i, 0);
                if (!(v >= 0 && v < double(pos.count()))) throw Failure{2, "index " + number(v) + " beyond the vertex count"};
                idx[i] = size_t(v);
            }
        } else {
            idx.resize(pos.count());
            for (size_t i = 0; i < idx.size(); i++) idx[i] = i;
        }
        // Hulls are plain triangle lists (as Sylva writes them); each instance is hulls of its own.
        hulls = hulls && mode == TINYGLTF_MODE_TRIANGLES;
        int map = want_cut ? alpha_map(prim.material) : -1;
        std::unique_ptr<AccessorView> tc;
        if (map >= 0 && maps[size_t(map)].w * maps[size_t(map)].h > 1) {
            auto t = prim.attributes.find("TEXCOORD_0");
            if (t != prim.attributes.end()) tc.reset(new AccessorView(m, t->second, "TEXCOORD_0"));
            if (!tc || tc->components() != 2 || tc->count() != pos.count()) map = -1, tc.reset(); // untextured: drawn whole
        }
        std::vector<size_t> part = hulls ? components(idx, pos.count()) : std::vector<size_t>();
        size_t n_parts = 0;
        for (size_t p : part) n_parts = std::max(n_parts, p + 1);
        for (const Mat4 &xf : xfs) {
            if (mode == TINYGLTF_MODE_TRIANGLES)
                for (size_t i = 0; i + 2 < idx.size(); i += 3)
                    emit(xf, pos, idx[i], idx[i + 1], idx[i + 2], hulls ? n_hulls + 1 + part[i / 3] : 0, tc.get(), map);
            else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP)
                for (size_t i = 0; i + 2 < idx.size(); i++)
                    i % 2 ? emit(xf, pos, idx[i + 1], idx[i], idx[i + 2], 0, tc.get(), map)
                          : emit(xf, pos, idx[i], idx[i + 1], idx[i + 2], 0, tc.get(), map);
            else
                for (size_t i = 1; i + 1 < idx.size(); i++) emit(xf, pos, idx[0], idx[i], idx[i + 1], 0, tc.get(), map);
            n_hulls += n_parts;
        }
    }

    void node(int index, const Mat4 &parent, int depth)
    {
        if (index < 0 || size_t(index) >= m.nodes.size()) throw Failure{2, "node index out of range"};
        if (depth > 256) throw Failure{2, "node hierarchy deeper than 256 (a cycle?)"};
        // Shared children make the hierarchy a DAG that can blow up exponentially.
        if (++visits > 4 * m.nodes.size() + 1000000) throw Failure{2, "node hierarchy visits too many nodes"};
        const tinygltf::Node &n = m.nodes[size_t(index)];
        Mat4 world = mul(parent, local_transform(n));
        if (n.mesh >= 0) {
            if (size_t(n.mesh) >= m.meshes.size()) throw Failure{2, "mesh index out of range"};
            std::vector<Mat4> xfs = instances(n);
            for (Mat4 &x : xfs) x = mul(world, x);
            const tinygltf::Mesh &mesh = m.meshes[size_t(n.mesh)];
            for (const tinygltf::Primitive &p : mesh.primitives) primitive(p, xfs, mesh.name == kHullMesh);
        }
        for (int c : n.children) node(c, world, depth + 1);
    }
};

// External buffers (a .gltf's "uri"): regular files only, of a bounded size.
// tinygltf's own reader would open a FIFO named there and wait forever, or
// read a device; an accessor can never need more than 2 GiB of one buffer.
constexpr long long kMaxExternalBuffer = 1LL << 31;

bool regular_file(const std::string &path, long long *size)
{
    struct stat st;
    if (stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return false;
    *size = (long long)st.st_size;
    return true;
}

bool fs_exists(const std::string &path, void *)
{
    long long size;
    return regular_file(path, &size);
}

std::string fs_expand(const std::string &path, void *) { return path; }

bool fs_read(std::vector<unsigned char> *out, std::string *err, const std::string &path, void *)
{
    long long size;
    if (!regular_file(path, &size)) {
        if (err) *err += "not a regular file: " + path + "\n";
        return false;
    }
    if (size > kMaxExternalBuffer) {
        if (err) *err += "file larger than 2 GiB: " + path + "\n";
        return false;
    }
    FILE *fp = std::fopen(path.c_str(), "rb");
    if (!fp) {
        if (err) *err += "cannot open " + path + "\n";
        return false;
    }
    out->resize(size_t(size));
    size_t got = size ? std::fread(out->data(), 1, size_t(size), fp) : 0;
    std::fclose(fp);
    if (got != size_t(size)) {
        if (err) *err += "short read: " + path + "\n";
        return false;
    }
    return true;
}

bool fs_write(std::string *err, const std::string &, const std::vector<unsigned char> &, void *)
{
    if (err) *err += "writing is not allowed here\n";
    return false;
}

// Evaluation needs geometry only: skip decoding textures.
bool skip_image(tinygltf::Image *, const int, std::string *, std::string *, int, int, const unsigned char *, int, void *)
{
    return true;
}

// The alpha test (sy_gltf_read_surface) reads what images it can and draws a
// triangle whole where its image is unreadable: a format stb does not decode
// (WebP, KTX2) or one over kMaxCutPixels (a few bytes of a crafted header
// would otherwise cost gigabytes) is left empty, and the file still loads.
// An image without alpha is left empty too: an empty image and an opaque
// one give the same map, the factor's alpha alone (alpha_map; a material
// whose primitive lacks the TEXCOORD_0 its texture needs, invalid glTF, is
// then cut by that alpha instead of drawn whole), and a tree's bark, normal
// and impostor maps need not be decoded to be measured. Without alpha: stb's
// header says grey or RGB (1 or 3 components), and it is no grey or RGB PNG
// with a tRNS chunk (stb's header scan stops at such a PNG's IHDR and says 1
// or 3, though decoding gives it an alpha channel; a paletted PNG it scans on
// to its tRNS).
constexpr long long kMaxCutPixels = 8192LL * 8192LL;

bool png_grey_or_rgb_with_trns(const unsigned char *b, int size)
{
    static const unsigned char sig[8] = {137, 80, 78, 71, 13, 10, 26, 10};
    if (size < 33 || std::memcmp(b, sig, 8) != 0 || std::memcmp(b + 12, "IHDR", 4) != 0) return false;
    if (b[25] != 0 && b[25] != 2) return false; // colour type: grey or RGB
    long long at = 8;
    while (at + 8 <= size) {
        unsigned long len = (unsigned long)b[at] << 24 | (unsigned long)b[at + 1] << 16 | (unsigned long)b[at + 2] << 8 | b[at + 3];
        const unsigned char *type = b + at + 4;
        if (std::memcmp(type, "tRNS", 4) == 0) return true;
        if (std::memcmp(type, "IDAT", 4) == 0 || std::memcmp(type, "IEND", 4) == 0) return false;
        at += 12 + (long long)len;
    }
    return false;
}

bool lenient_image(tinygltf::Image *image, const int index, std::string *err, std::string *warn, int req_width,
                   int req_height, const unsigned char *bytes, int size, void *user)
{
    int w = 0, h = 0, c = 0;
    if (size <= 0 || !stbi_info_from_memory(bytes, size, &w, &h, &c) || (long long)w * h > kMaxCutPixels) return true;
    if ((c == 1 || c == 3) && !png_grey_or_rgb_with_trns(bytes, size)) return true;
    std::string e, wn;
    if (!tinygltf::LoadImageData(image, index, &e, &wn, req_width, req_height, bytes, size, user)) {
        image->image.clear();
        image->width = image->height = 0;
    }
    (void)err, (void)warn;
    return true;
}

void set_msg(char *msg, size_t size, const char *path, const std::string &what)
{
    std::string one = what;
    for (char &ch : one)
        if (ch == '\n' || ch == '\r') ch = ' ';
    while (!one.empty() && one.back() == ' ') one.pop_back();
    std::snprintf(msg, size, "%s: %s", path, one.c_str());
}


// EXT_meshopt_compression: every compressed bufferView is decoded into a buffer of its own and
// the view pointed at it, so accessors read plain data (tinygltf leaves the extension alone).
void decode_meshopt(tinygltf::Model &m)
{
    for (size_t i = 0; i < m.bufferViews.size(); i++) {
        tinygltf::BufferView &bv = m.bufferViews[i];
        auto it = bv.extensions.find("EXT_meshopt_compression");
        if (it == bv.extensions.end()) continue;
        const tinygltf::Value &e = it->second;
        std::string what = "EXT_meshopt_compression of bufferView " + std::to_string(i);
        auto num = [&](const char *k, double dflt) {
            if (!e.IsObject() || !e.Has(k)) return dflt;
            const tinygltf::Value &v = e.Get(k);
            if (!v.IsNumber()) throw Failure{2, what + ": " + k + " is not a number"};
            return v.GetNumberAsDouble();
        };
        auto str = [&](const char *k, const char *dflt) {
            return e.IsObject() && e.Has(k) && e.Get(k).IsString() ? e.Get(k).Get<std::string>() : std::string(dflt);
        };
        double buffer = num("buffer", -1), offset = num("byteOffset", 0), length = num("byteLength", -1), stride = num("byteStride", -1),
               count = num("count", -1);
        std::string mode = str("mode", ""), filter = str("filter", "NONE");
        if (!(buffer >= 0 && buffer < double(m.buffers.size()))) throw Failure{2, what + " names a missing buffer"};
        const std::vector<unsigned char> &src = m.buffers[size_t(buffer)].data;
        if (!(offset >= 0 && length >= 0 && offset + length <= double(src.size()))) throw Failure{2, what + " lies outside its buffer"};
        if (!(stride >= 1 && stride <= 256 && count >= 0 && count * stride <= double(1u << 31)))
            throw Failure{2, what + " has an invalid byteStride or count"};
        std::vector<unsigned char> out(size_t(count) * size_t(stride));
        const unsigned char *data = src.data() + size_t(offset);
        int rc = -1;
        if (mode == "ATTRIBUTES" && size_t(stride) % 4 == 0)
            rc = meshopt_decodeVertexBuffer(out.data(), size_t(count), size_t(stride), data, size_t(length));
        else if (mode == "TRIANGLES" && (stride == 2 || stride == 4) && size_t(count) % 3 == 0)
            rc = meshopt_decodeIndexBuffer(out.data(), size_t(count), size_t(stride), data, size_t(length));
        else if (mode == "INDICES" && (stride == 2 || stride == 4))
            rc = meshopt_decodeIndexSequence(out.data(), size_t(count), size_t(stride), data, size_t(length));
        else
            throw Failure{2, what + " has an unknown mode '" + mode + "' for its stride"};
        if (rc != 0) throw Failure{2, what + " does not decode"};
        if (filter == "OCTAHEDRAL" && (stride == 4 || stride == 8)) meshopt_decodeFilterOct(out.data(), size_t(count), size_t(stride));
        else if (filter == "QUATERNION" && stride == 8) meshopt_decodeFilterQuat(out.data(), size_t(count), size_t(stride));
        else if (filter == "EXPONENTIAL" && size_t(stride) % 4 == 0) meshopt_decodeFilterExp(out.data(), size_t(count), size_t(stride));
        else if (filter != "NONE") throw Failure{2, what + " has an unknown filter '" + filter + "'"};
        tinygltf::Buffer decoded;
        decoded.data.swap(out);
        m.buffers.push_back(std::move(decoded));
        bv.buffer = int(m.buffers.size() - 1);
        bv.byteOffset = 0;
        bv.byteLength = m.buffers.back().data.size();
        bv.byteStride = mode == "ATTRIBUTES" ? size_t(stride) : 0;
    }
}

// Loads a .glb or .gltf (told apart by the GLB magic); false with msg set on failure.
// images: decode them (the scene reader), or those that can be (the alpha test), or skip them.
enum Images { kSkipImages, kDecodeImages, kDecodeReadableImages };

bool load_model(const char *path, tinygltf::Model &model, Images images, char *msg, size_t msg_size)
{
    tinygltf::TinyGLTF loader;
    if (images == kSkipImages) loader.SetImageLoader(skip_image, nullptr);
    if (images == kDecodeReadableImages) loader.SetImageLoader(lenient_image, nullptr);
    // External buffers and images: regular files of a bounded size only (a FIFO would hang the read).
    loader.SetFsCallbacks(tinygltf::FsCallbacks{fs_exists, fs_expand, fs_read, fs_write, nullptr});
    std::string err, warn;
    FILE *fp = std::fopen(path, "rb");
    if (!fp) {
        set_msg(msg, msg_size, path, "cannot open");
        return false;
    }
    unsigned char magic[4] = {0, 0, 0, 0};
    size_t got = std::fread(magic, 1, 4, fp);
    std::fclose(fp);
    bool binary = got == 4 && std::memcmp(magic, "glTF", 4) == 0;
    bool ok = binary ? loader.LoadBinaryFromFile(&model, &err, &warn, path) : loader.LoadASCIIFromFile(&model, &err, &warn, path);
    if (!ok) set_msg(msg, msg_size, path, err.empty() ? "not a readable glTF file" : "invalid glTF: " + err);
    else decode_meshopt(model);
    return ok;
}

// The default scene's root nodes (or scene 0's); with no scene, every node that is nobody's child.
std::vector<int> scene_roots(const tinygltf::Model &model)
{
    std::vector<int> roots;
    if (!model.scenes.empty()) {
        int s = model.defaultScene >= 0 ? model.defaultScene : 0;
        if (size_t(s) >= model.scenes.size()) throw Failure{2, "default scene index out of range"};
        return model.scenes[size_t(s)].nodes;
    }
    std::vector<char> child(model.nodes.size(), 0);
    for (const auto &n : model.nodes)
        for (int c : n.children)
            if (c >= 0 && size_t(c) < child.size()) child[size_t(c)] = 1;
    for (size_t i = 0; i < model.nodes.size(); i++)
        if (!child[i]) roots.push_back(int(i));
    return roots;
}

// asset.extras.origin [x, y, z] when present: the world position (Z up) of the glTF origin.
bool asset_origin(const tinygltf::Model &model, double o[3])
{
    if (!model.asset.extras.IsObject()) return false;
    const tinygltf::Value &origin = model.asset.extras.Get("origin");
    if (!(origin.IsArray() && origin.ArrayLen() == 3 && origin.Get(0).IsNumber() && origin.Get(1).IsNumber() && origin.Get(2).IsNumber()))
        return false;
    for (int c = 0; c < 3; c++) o[c] = origin.Get(c).GetNumberAsDouble();
    return true;
}

} // namespace

static float *c_floats(const std::vector<float> &v)
{
    float *p = static_cast<float *>(std::malloc(v.size() * sizeof(float) + 1));
    if (!p) throw std::bad_alloc();
    if (!v.empty()) std::memcpy(p, v.data(), v.size() * sizeof(float));
    return p;
}

// cut non-NULL: also the triangles' cut-out (images decoded), filled only on success.
static int read_triangles(const char *path, double **tri, size_t *n_tri, size_t **hull, sy_gltf_cutout *cut, char *msg,
                          size_t msg_size)
{
    *tri = nullptr;
    *hull = nullptr;
    *n_tri = 0;
    try {
        tinygltf::Model model;
        if (!load_model(path, model, cut ? kDecodeReadableImages : kSkipImages, msg, msg_size)) return 2;
        Reader r(model);
        r.want_cut = cut != nullptr;
        std::vector<int> roots = scene_roots(model);
        for (int n : roots) r.node(n, identity(), 0);
        // `sylva mesh` centres the tree at its base and keeps the world position
        // of that point in asset.extras.origin (Z up): put the tree back there.
        double origin[3];
        if (asset_origin(model, origin))
            for (size_t i = 0; i < r.out.size(); i++) {
                r.out[i] += origin[i % 3];
                if (!(std::fabs(r.out[i]) <= kMaxCoordinate))
                    throw Failure{2, "asset.extras.origin puts a vertex at " + number(r.out[i]) + " m (beyond 1e9 m)"};
            }
        *n_tri = r.out.size() / 9;
        *tri = static_cast<double *>(std::malloc(r.out.size() ? r.out.size() * sizeof(double) : sizeof(double)));
        *hull = static_cast<size_t *>(std::malloc(r.hull.size() ? r.hull.size() * sizeof(size_t) : sizeof(size_t)));
        if (!*tri || !*hull) {
            std::free(*tri);
            std::free(*hull);
            *tri = nullptr;
            *hull = nullptr;
            *n_tri = 0;
            set_msg(msg, msg_size, path, "out of memory");
            return 3;
        }
        if (!r.out.empty()) std::memcpy(*tri, r.out.data(), r.out.size() * sizeof(double));
        if (!r.hull.empty()) std::memcpy(*hull, r.hull.data(), r.hull.size() * sizeof(size_t));
        if (cut) {
            *cut = sy_gltf_cutout{nullptr, nullptr, 0, nullptr};
            try {
                if (!r.maps.empty()) {
                    cut->uv = c_floats(r.uv);
                    cut->map = static_cast<int32_t *>(std::malloc(r.tmap.size() * sizeof(int32_t) + 1));
                    cut->maps = static_cast<sy_gltf_alpha_map *>(std::calloc(r.maps.size(), sizeof(sy_gltf_alpha_map)));
                    if (!cut->map || !cut->maps) throw std::bad_alloc();
                    if (!r.tmap.empty()) std::memcpy(cut->map, r.tmap.data(), r.tmap.size() * sizeof(int32_t));
                    cut->n_maps = r.maps.size();
                    for (size_t i = 0; i < r.maps.size(); i++) {
                        cut->maps[i] = r.maps[i];
                        cut->maps[i].alpha = static_cast<unsigned char *>(std::malloc(r.alphas[i].size()));
                        if (!cut->maps[i].alpha) throw std::bad_alloc();
                        std::memcpy(cut->maps[i].alpha, r.alphas[i].data(), r.alphas[i].size());
                    }
                }
            } catch (const std::bad_alloc &) {
                sy_gltf_cutout_free(cut);
                std::free(*tri);
                std::free(*hull);
                *tri = nullptr;
                *hull = nullptr;
                *n_tri = 0;
                set_msg(msg, msg_size, path, "out of memory");
                return 3;
            }
        }
        return 0;
    } catch (const Failure &f) {
        set_msg(msg, msg_size, path, f.what);
        return f.code;
    } catch (const std::bad_alloc &) {
        set_msg(msg, msg_size, path, "out of memory");
        return 3;
    } catch (const std::exception &e) {
        set_msg(msg, msg_size, path, std::string("invalid glTF: ") + e.what());
        return 2;
    }
}

extern "C" sy_code sy_gltf_read_triangles(const char *path, double **tri, size_t *n_tri, size_t **hull, sy_error *err)
{
    char msg[1024];
    int rc = read_triangles(path, tri, n_tri, hull, nullptr, msg, sizeof msg);
    if (rc == 0) return SY_OK;
    return sy_fail(err, rc == 3 ? SY_EINTERNAL : SY_EINPUT, "%s", msg);
}

extern "C" void sy_gltf_cutout_free(sy_gltf_cutout *c)
{
    if (!c) return;
    for (size_t i = 0; i < c->n_maps; i++) std::free(c->maps[i].alpha);
    std::free(c->maps), std::free(c->map), std::free(c->uv);
    *c = sy_gltf_cutout{nullptr, nullptr, 0, nullptr};
}

extern "C" sy_code sy_gltf_read_surface(const char *path, double **tri, size_t *n_tri, sy_gltf_cutout *cut, sy_error *err)
{
    char msg[1024];
    size_t *hull = nullptr;
    if (cut) *cut = sy_gltf_cutout{nullptr, nullptr, 0, nullptr};
    int rc = read_triangles(path, tri, n_tri, &hull, cut, msg, sizeof msg);
    if (rc) return sy_fail(err, rc == 3 ? SY_EINTERNAL : SY_EINPUT, "%s", msg);
    // The foliage proxy is no surface a viewer draws as the tree.
    size_t k = 0;
    for (size_t t = 0; t < *n_tri; t++) {
        if (hull[t]) continue;
        std::memmove(*tri + 9 * k, *tri + 9 * t, 9 * sizeof **tri);
        if (cut && cut->map) {
            cut->map[k] = cut->map[t];
            std::memmove(cut->uv + 6 * k, cut->uv + 6 * t, 6 * sizeof *cut->uv);
        }
        k++;
    }
    std::free(hull);
    *n_tri = k;
    return SY_OK;
}

extern "C" int sy_gltf_cutout_drawn(const sy_gltf_cutout *cut, size_t t, const double w[3])
{
    if (!cut || !cut->map || cut->map[t] < 0) return 1;
    const sy_gltf_alpha_map *am = &cut->maps[cut->map[t]];
    const float *uv = cut->uv + 6 * t;
    double u = w[0] * uv[0] + w[1] * uv[2] + w[2] * uv[4], v = w[0] * uv[1] + w[1] * uv[3] + w[2] * uv[5];
    if (!std::isfinite(u) || !std::isfinite(v)) return 1;
    // REPEAT: the texel under (u, v), nearest.
    long x = long(std::floor((u - std::floor(u)) * am->w)), y = long(std::floor((v - std::floor(v)) * am->h));
    x = x < 0 ? 0 : x >= am->w ? am->w - 1 : x;
    y = y < 0 ? 0 : y >= am->h ? am->h - 1 : y;
    return am->alpha[size_t(y) * size_t(am->w) + size_t(x)] >= am->cutoff * 255.0f;
}

// ---------------------------------------------------------------------------
// The scene for drawing (sy_gltf_read_scene).

namespace {

template <typename T> T *c_copy(const std::vector<T> &v)
{
    if (v.empty()) return nullptr;
    T *p = static_cast<T *>(std::malloc(v.size() * sizeof(T)));
    if (!p) throw std::bad_alloc();
    std::memcpy(p, v.data(), v.size() * sizeof(T));
    return p;
}

void copy_name(char *dst, size_t size, const std::string &s) { std::snprintf(dst, size, "%s", s.c_str()); }

// Reads a whole float attribute of `width` components (or NULL when absent).
float *read_attribute(const tinygltf::Model &m, const std::map<std::string, int> &attrs, const char *name, int width,
                      size_t n_expected, bool allow_vec3_for_vec4 = false)
{
    auto it = attrs.find(name);
    if (it == attrs.end()) return nullptr;
    AccessorView v(m, it->second, name);
    int comps = v.components();
    if (comps != width && !(allow_vec3_for_vec4 && comps == 3 && width == 4))
        throw Failure{2, std::string(name) + " has " + std::to_string(comps) + " components, expected " + std::to_string(width)};
    if (v.count() != n_expected) throw Failure{2, std::string(name) + " count differs from POSITION"};
    std::vector<float> out(n_expected * size_t(width));
    for (size_t i = 0; i < n_expected; i++)
        for (int c = 0; c < width; c++) {
            double x = c < comps ? v.get(i, c) : 1.0;
            if (!std::isfinite(x)) throw Failure{2, std::string(name) + " holds a NaN or infinite value"};
            out[i * size_t(width) + size_t(c)] = float(x);
        }
    return c_copy(out);
}

struct SceneBuilder {
    const tinygltf::Model &m;
    sy_gltf_scene &s;
    std::vector<sy_gltf_primitive> prims;
    std::vector<sy_gltf_mesh> meshes;
    std::vector<sy_gltf_draw> draws;
    std::vector<sy_gltf_object> objects;
    size_t visits = 0;

    // What was not handed to the scene yet (a failure part way) is freed here.
    ~SceneBuilder()
    {
        for (sy_gltf_primitive &p : prims) {
            for (float *f : {p.position, p.normal, p.tangent, p.uv, p.color, p.wind_w, p.wind_branch, p.wind_anchor, p.wind_level_stiffness})
                std::free(f);
            std::free(p.indices);
        }
        for (sy_gltf_draw &d : draws)
            for (float *f : {d.instance_matrix, d.inst_wind_w, d.inst_wind_branch, d.inst_wind_anchor, d.inst_wind_level_stiffness}) std::free(f);
        for (sy_gltf_object &o : objects) std::free(o.wind);
    }

    int texture_ref(int index, const char *what)
    {
        if (index < 0) return -1;
        if (size_t(index) >= m.textures.size()) throw Failure{2, std::string(what) + " names texture " + std::to_string(index) + ", which does not exist"};
        const tinygltf::Texture &t = m.textures[size_t(index)];
        if (t.source < 0 || size_t(t.source) >= m.images.size()) throw Failure{2, std::string(what) + ": texture " + std::to_string(index) + " has no image"};
        return index;
    }

    void build_images()
    {
        s.n_images = m.images.size();
        if (!s.n_images) return;
        s.images = static_cast<sy_gltf_image *>(std::calloc(s.n_images, sizeof(sy_gltf_image)));
        if (!s.images) throw std::bad_alloc();
        for (size_t i = 0; i < m.images.size(); i++) {
            const tinygltf::Image &im = m.images[i];
            if (im.width <= 0 || im.height <= 0 || im.image.empty())
                throw Failure{2, "image " + std::to_string(i) + (im.uri.empty() ? "" : " (" + im.uri + ")") + " did not decode"};
            if (im.width > 16384 || im.height > 16384) throw Failure{2, "image " + std::to_string(i) + " is larger than 16384 pixels"};
            int bits = im.bits == 16 ? 16 : 8, bytes = bits / 8, comps = im.component;
            if (comps < 1 || comps > 4 || (im.bits != 8 && im.bits != 16)) throw Failure{2, "image " + std::to_string(i) + " has an unsupported pixel format"};
            size_t n = size_t(im.width) * size_t(im.height);
            if (im.image.size() < n * size_t(comps * bytes)) throw Failure{2, "image " + std::to_string(i) + " is truncated"};
            unsigned char *px = static_cast<unsigned char *>(std::malloc(n * 4 * size_t(bytes)));
            if (!px) throw std::bad_alloc();
            // Grey spreads to RGB; a missing alpha is opaque.
            static const int kSource[5][4] = {{0, 0, 0, -1}, {0, 0, 0, -1}, {0, 0, 0, 1}, {0, 1, 2, -1}, {0, 1, 2, 3}};
            for (size_t p = 0; p < n; p++)
                for (int c = 0; c < 4; c++) {
                    int src = kSource[comps][c];
                    for (int b = 0; b < bytes; b++)
                        px[(p * 4 + size_t(c)) * size_t(bytes) + size_t(b)] =
                            src < 0 ? 255 : im.image[(p * size_t(comps) + size_t(src)) * size_t(bytes) + size_t(b)];
                }
            s.images[i].width = im.width;
            s.images[i].height = im.height;
            s.images[i].bits = bits;
            s.images[i].pixels = px;
        }
    }

    void build_textures()
    {
        s.n_textures = m.textures.size();
        if (!s.n_textures) return;
        s.textures = static_cast<sy_gltf_texture *>(std::calloc(s.n_textures, sizeof(sy_gltf_texture)));
        if (!s.textures) throw std::bad_alloc();
        for (size_t i = 0; i < m.textures.size(); i++) {
            const tinygltf::Texture &t = m.textures[i];
            sy_gltf_texture &o = s.textures[i];
            o.image = t.source;
            o.wrap_s = o.wrap_t = TINYGLTF_TEXTURE_WRAP_REPEAT;
            o.min_filter = o.mag_filter = -1;
            if (t.sampler >= 0) {
                if (size_t(t.sampler) >= m.samplers.size()) throw Failure{2, "texture " + std::to_string(i) + " names a missing sampler"};
                const tinygltf::Sampler &sm = m.samplers[size_t(t.sampler)];
                o.wrap_s = sm.wrapS, o.wrap_t = sm.wrapT, o.min_filter = sm.minFilter, o.mag_filter = sm.magFilter;
            }
        }
    }

    static float number(const tinygltf::Value &v, const char *key, float dflt)
    {
        if (!v.IsObject() || !v.Has(key)) return dflt;
        const tinygltf::Value &x = v.Get(key);
        return x.IsNumber() ? float(x.GetNumberAsDouble()) : dflt;
    }

    int texture_in(const tinygltf::Value &v, const char *key, const char *what)
    {
        if (!v.IsObject() || !v.Has(key)) return -1;
        const tinygltf::Value &t = v.Get(key);
        // A textureInfo object ({"index": i}) or a bare index.
        if (t.IsObject() && t.Has("index") && t.Get("index").IsNumber()) return texture_ref(t.Get("index").GetNumberAsInt(), what);
        if (t.IsNumber()) return texture_ref(t.GetNumberAsInt(), what);
        throw Failure{2, std::string(what) + "." + key + " is not a texture reference"};
    }

    void build_materials()
    {
        s.n_materials = m.materials.size();
        if (!s.n_materials) return;
        s.materials = static_cast<sy_gltf_material *>(std::calloc(s.n_materials, sizeof(sy_gltf_material)));
        if (!s.materials) throw std::bad_alloc();
        for (size_t i = 0; i < m.materials.size(); i++) {
            const tinygltf::Material &mt = m.materials[i];
            sy_gltf_material &o = s.materials[i];
            std::string what = "material " + std::to_string(i);
            copy_name(o.name, sizeof o.name, mt.name);
            const auto &pbr = mt.pbrMetallicRoughness;
            for (int c = 0; c < 4; c++) o.base_color[c] = pbr.baseColorFactor.size() == 4 ? float(pbr.baseColorFactor[size_t(c)]) : 1.0f;
            o.metallic = float(pbr.metallicFactor);
            o.roughness = float(pbr.roughnessFactor);
            o.base_color_texture = texture_ref(pbr.baseColorTexture.index, what.c_str());
            o.metallic_roughness_texture = texture_ref(pbr.metallicRoughnessTexture.index, what.c_str());
            o.normal_texture = texture_ref(mt.normalTexture.index, what.c_str());
            o.normal_scale = float(mt.normalTexture.scale);
            for (int c = 0; c < 3; c++) o.emissive[c] = mt.emissiveFactor.size() == 3 ? float(mt.emissiveFactor[size_t(c)]) : 0.0f;
            o.alpha_mode = mt.alphaMode == "MASK" ? SY_GLTF_MASK : mt.alphaMode == "BLEND" ? SY_GLTF_BLEND : SY_GLTF_OPAQUE;
            o.alpha_cutoff = float(mt.alphaCutoff);
            o.double_sided = mt.doubleSided;
            o.diffuse_transmission_texture = o.diffuse_transmission_color_texture = -1;
            o.hl2_adaxial_texture = o.hl2_abaxial_texture = -1;
            o.hl2_min = -1, o.hl2_max = 3;
            auto dt = mt.extensions.find("KHR_materials_diffuse_transmission");
            if (dt != mt.extensions.end()) {
                const tinygltf::Value &v = dt->second;
                o.diffuse_transmission = number(v, "diffuseTransmissionFactor", 0);
                for (int c = 0; c < 3; c++) o.diffuse_transmission_color[c] = 1;
                if (v.IsObject() && v.Has("diffuseTransmissionColorFactor")) {
                    const tinygltf::Value &col = v.Get("diffuseTransmissionColorFactor");
                    if (col.IsArray() && col.ArrayLen() == 3)
                        for (int c = 0; c < 3; c++) o.diffuse_transmission_color[c] = float(col.Get(c).GetNumberAsDouble());
                }
                o.diffuse_transmission_texture = texture_in(v, "diffuseTransmissionTexture", what.c_str());
                o.diffuse_transmission_color_texture = texture_in(v, "diffuseTransmissionColorTexture", what.c_str());
            }
            auto lt = mt.extensions.find("SYLVA_leaf_translucency");
            if (lt != mt.extensions.end()) {
                const tinygltf::Value &h = lt->second;
                if (!h.IsObject()) throw Failure{2, what + ": SYLVA_leaf_translucency is not an object"};
                o.hl2_adaxial_texture = texture_in(h, "adaxialTexture", what.c_str());
                o.hl2_abaxial_texture = texture_in(h, "abaxialTexture", what.c_str());
                o.hl2_min = number(h, "decodeMin", -1);
                o.hl2_max = number(h, "decodeMax", 3);
                if (!(std::isfinite(o.hl2_min) && std::isfinite(o.hl2_max)))
                    throw Failure{2, what + ": SYLVA_leaf_translucency decodeMin/decodeMax are not finite"};
            }
        }
    }

    void build_meshes()
    {
        for (size_t mi = 0; mi < m.meshes.size(); mi++) {
            const tinygltf::Mesh &mesh = m.meshes[mi];
            sy_gltf_mesh om{};
            copy_name(om.name, sizeof om.name, mesh.name);
            om.first_primitive = int(prims.size());
            for (const tinygltf::Primitive &pr : mesh.primitives) {
                int mode = pr.mode < 0 ? TINYGLTF_MODE_TRIANGLES : pr.mode;
                if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN) continue;
                auto pit = pr.attributes.find("POSITION");
                if (pit == pr.attributes.end()) continue;
                if (pr.material >= 0 && size_t(pr.material) >= m.materials.size())
                    throw Failure{2, "mesh " + std::to_string(mi) + " names a missing material"};
                sy_gltf_primitive p{};
                p.material = pr.material;
                prims.push_back(p); // owned by the scene from here on (freed on failure)
                sy_gltf_primitive &q = prims.back();
                AccessorView pos(m, pit->second, "POSITION");
                if (pos.components() != 3) throw Failure{2, "POSITION is not a VEC3 accessor"};
                q.n_vertices = pos.count();
                q.position = read_attribute(m, pr.attributes, "POSITION", 3, q.n_vertices);
                q.normal = read_attribute(m, pr.attributes, "NORMAL", 3, q.n_vertices);
                q.tangent = read_attribute(m, pr.attributes, "TANGENT", 4, q.n_vertices);
                q.uv = read_attribute(m, pr.attributes, "TEXCOORD_0", 2, q.n_vertices);
                q.color = read_attribute(m, pr.attributes, "COLOR_0", 4, q.n_vertices, true);
                q.wind_w = read_attribute(m, pr.attributes, "_WIND_W", 4, q.n_vertices);
                q.wind_branch = read_attribute(m, pr.attributes, "_WIND_BRANCH", 1, q.n_vertices);
                q.wind_anchor = read_attribute(m, pr.attributes, "_WIND_ANCHOR", 3, q.n_vertices);
                q.wind_level_stiffness = read_attribute(m, pr.attributes, "_WIND_LEVEL_STIFFNESS", 2, q.n_vertices);
                std::vector<uint32_t> raw;
                if (pr.indices >= 0) {
                    AccessorView ind(m, pr.indices, "index");
                    raw.resize(ind.count());
                    for (size_t i = 0; i < ind.count(); i++) {
                        double v = ind.get(i, 0);
                        if (!(v >= 0 && v < double(q.n_vertices))) throw Failure{2, "index " + std::to_string(size_t(v)) + " beyond the vertex count"};
                        raw[i] = uint32_t(v);
                    }
                } else {
                    if (q.n_vertices > 0xffffffffu) throw Failure{2, "more than 2^32 vertices in a primitive"};
                    raw.resize(q.n_vertices);
                    for (size_t i = 0; i < raw.size(); i++) raw[i] = uint32_t(i);
                }
                std::vector<uint32_t> tri;
                if (mode == TINYGLTF_MODE_TRIANGLES) {
                    raw.resize(raw.size() / 3 * 3);
                    tri.swap(raw);
                } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
                    for (size_t i = 0; i + 2 < raw.size(); i++) {
                        uint32_t a = raw[i], b = raw[i + 1], c = raw[i + 2];
                        if (i % 2) std::swap(a, b);
                        tri.insert(tri.end(), {a, b, c});
                    }
                } else {
                    for (size_t i = 1; i + 1 < raw.size(); i++) tri.insert(tri.end(), {raw[0], raw[i], raw[i + 1]});
                }
                q.n_indices = tri.size();
                q.indices = c_copy(tri);
            }
            om.n_primitives = int(prims.size()) - om.first_primitive;
            meshes.push_back(om);
        }
    }

    // EXT_mesh_gpu_instancing: TRS matrices and Sylva's per-instance wind.
    void instances(const tinygltf::Node &n, sy_gltf_draw &d)
    {
        auto it = n.extensions.find("EXT_mesh_gpu_instancing");
        if (it == n.extensions.end() || !it->second.IsObject() || !it->second.Has("attributes")) return;
        const tinygltf::Value &attrs = it->second.Get("attributes");
        if (!attrs.IsObject()) throw Failure{2, "EXT_mesh_gpu_instancing attributes is not an object"};
        size_t count = 0;
        bool any = false;
        auto view = [&](const char *name, int width) -> std::unique_ptr<AccessorView> {
            if (!attrs.Has(name)) return nullptr;
            const tinygltf::Value &v = attrs.Get(name);
            if (!v.IsNumber()) throw Failure{2, std::string("EXT_mesh_gpu_instancing ") + name + " is not an accessor index"};
            std::unique_ptr<AccessorView> a(new AccessorView(m, v.GetNumberAsInt(), "EXT_mesh_gpu_instancing"));
            if (a->components() != width) throw Failure{2, std::string("EXT_mesh_gpu_instancing ") + name + " has the wrong type"};
            if (any && a->count() != count) throw Failure{2, "EXT_mesh_gpu_instancing attributes differ in count"};
            count = a->count();
            any = true;
            return a;
        };
        auto t = view("TRANSLATION", 3), r = view("ROTATION", 4), sc = view("SCALE", 3);
        auto ww = view("_WIND_W", 4), wb = view("_WIND_BRANCH", 1), wa = view("_WIND_ANCHOR", 3), wl = view("_WIND_LEVEL_STIFFNESS", 2);
        if (!any) return;
        std::vector<float> mat(count * 16);
        for (size_t i = 0; i < count; i++) {
            double tt[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, ss[3] = {1, 1, 1};
            for (int c = 0; c < 3; c++) {
                if (t) tt[c] = t->get(i, c);
                if (sc) ss[c] = sc->get(i, c);
            }
            if (r) for (int c = 0; c < 4; c++) q[c] = r->get(i, c);
            Mat4 x = trs(tt, q, ss);
            for (int k = 0; k < 16; k++) {
                if (!std::isfinite(x[size_t(k)])) throw Failure{2, "EXT_mesh_gpu_instancing holds a NaN or infinite transform"};
                mat[i * 16 + size_t(k)] = float(x[size_t(k)]);
            }
        }
        d.n_instances = count;
        d.instance_matrix = c_copy(mat);
        auto grab = [&](const std::unique_ptr<AccessorView> &a, int width) -> float * {
            if (!a) return nullptr;
            std::vector<float> v(count * size_t(width));
            for (size_t i = 0; i < count; i++)
                for (int c = 0; c < width; c++) v[i * size_t(width) + size_t(c)] = float(a->get(i, c));
            return c_copy(v);
        };
        d.inst_wind_w = grab(ww, 4);
        d.inst_wind_branch = grab(wb, 1);
        d.inst_wind_anchor = grab(wa, 3);
        d.inst_wind_level_stiffness = grab(wl, 2);
    }

    void expand(sy_gltf_object &o, const Mat4 &w, const float *inst, size_t n_inst, const sy_gltf_mesh &mesh)
    {
        for (size_t k = 0; k < std::max<size_t>(n_inst, 1); k++) {
            Mat4 x = w;
            if (inst) {
                Mat4 im;
                for (int e = 0; e < 16; e++) im[size_t(e)] = inst[k * 16 + size_t(e)];
                x = mul(w, im);
            }
            for (int pi = 0; pi < mesh.n_primitives; pi++) {
                const sy_gltf_primitive &p = prims[size_t(mesh.first_primitive + pi)];
                for (size_t v = 0; v < p.n_vertices; v++) {
                    const float *q = p.position + 3 * v;
                    for (int r = 0; r < 3; r++) {
                        double c = x[size_t(r)] * q[0] + x[size_t(4 + r)] * q[1] + x[size_t(8 + r)] * q[2] + x[size_t(12 + r)];
                        o.bounds_min[r] = std::min(o.bounds_min[r], c);
                        o.bounds_max[r] = std::max(o.bounds_max[r], c);
                    }
                }
            }
        }
    }

    void node(int index, const Mat4 &parent, int depth, int object, int level)
    {
        if (index < 0 || size_t(index) >= m.nodes.size()) throw Failure{2, "node index out of range"};
        if (depth > 256) throw Failure{2, "node hierarchy deeper than 256 (a cycle?)"};
        if (++visits > 4 * m.nodes.size() + 1000000) throw Failure{2, "node hierarchy visits too many nodes"};
        const tinygltf::Node &n = m.nodes[size_t(index)];
        Mat4 world = mul(parent, local_transform(n));
        for (double v : world)
            if (!std::isfinite(v)) throw Failure{2, "node " + std::to_string(index) + " has a NaN or infinite transform"};
        if (n.mesh >= 0) {
            if (size_t(n.mesh) >= meshes.size()) throw Failure{2, "mesh index out of range"};
            sy_gltf_draw d{};
            d.mesh = n.mesh;
            d.object = object;
            d.level = level;
            for (int k = 0; k < 16; k++) d.world[k] = world[size_t(k)];
            draws.push_back(d);
            instances(n, draws.back());
            sy_gltf_draw &dd = draws.back();
            const sy_gltf_mesh &mesh = meshes[size_t(n.mesh)];
            size_t tris = 0;
            for (int pi = 0; pi < mesh.n_primitives; pi++) tris += prims[size_t(mesh.first_primitive + pi)].n_indices / 3;
            sy_gltf_object &o = objects[size_t(object)];
            o.n_triangles[level] += tris * std::max<size_t>(dd.n_instances, 1);
            if (level == 0) expand(o, world, dd.instance_matrix, dd.n_instances, mesh);
        }
        for (int c : n.children) node(c, world, depth + 1, object, level);
    }

    static std::vector<double> numbers(const tinygltf::Value &t, const char *key, size_t n)
    {
        if (!t.Has(key) || !t.Get(key).IsArray() || size_t(t.Get(key).ArrayLen()) != n)
            throw Failure{2, std::string("extras.sylva_wind.") + key + " is missing or has the wrong length"};
        const tinygltf::Value &a = t.Get(key);
        std::vector<double> out(n);
        for (size_t i = 0; i < n; i++) {
            const tinygltf::Value &x = a.Get(int(i));
            if (!x.IsNumber() || !std::isfinite(x.GetNumberAsDouble())) throw Failure{2, std::string("extras.sylva_wind.") + key + " holds a non-number"};
            out[i] = x.GetNumberAsDouble();
        }
        return out;
    }

    void wind_table(const tinygltf::Node &n, sy_gltf_object &o)
    {
        if (!n.extras.IsObject() || !n.extras.Has("sylva_wind")) return;
        const tinygltf::Value &t = n.extras.Get("sylva_wind");
        if (!t.IsObject() || !t.Has("count") || !t.Get("count").IsNumber()) throw Failure{2, "extras.sylva_wind has no count"};
        double cd = t.Get("count").GetNumberAsDouble();
        if (!(cd >= 0 && cd <= 1e6)) throw Failure{2, "extras.sylva_wind.count is out of range"};
        size_t cnt = size_t(cd);
        auto parent = numbers(t, "parent", cnt), level = numbers(t, "level", cnt), anchor = numbers(t, "anchor", 3 * cnt),
             axis = numbers(t, "axis", 3 * cnt), length = numbers(t, "length", cnt), c2 = numbers(t, "c2", cnt),
             c4 = numbers(t, "c4", cnt), freq = numbers(t, "frequency", cnt), stiff = numbers(t, "stiffness", cnt);
        std::vector<sy_gltf_wind_branch> w(cnt);
        for (size_t i = 0; i < cnt; i++) {
            if (parent[i] < -1 || parent[i] >= double(i) || parent[i] != std::floor(parent[i]))
                throw Failure{2, "extras.sylva_wind.parent[" + std::to_string(i) + "] does not name an earlier branch"};
            w[i].parent = int(parent[i]);
            w[i].level = int(std::min(std::max(level[i], 0.0), 3.0));
            for (int c = 0; c < 3; c++) w[i].anchor[c] = float(anchor[3 * i + size_t(c)]), w[i].axis[c] = float(axis[3 * i + size_t(c)]);
            w[i].length = float(length[i]);
            w[i].c2 = float(c2[i]);
            w[i].c4 = float(c4[i]);
            w[i].frequency = float(freq[i]);
            w[i].stiffness = float(stiff[i]);
        }
        o.n_wind = cnt;
        o.wind = c_copy(w);
    }

    void object(int root)
    {
        if (root < 0 || size_t(root) >= m.nodes.size()) throw Failure{2, "scene root node index out of range"};
        const tinygltf::Node &n = m.nodes[size_t(root)];
        sy_gltf_object o{};
        copy_name(o.name, sizeof o.name, n.name.empty() ? "node " + std::to_string(root) : n.name);
        for (int r = 0; r < 3; r++) o.bounds_min[r] = HUGE_VAL, o.bounds_max[r] = -HUGE_VAL;
        std::vector<int> levels{root};
        auto lod = n.extensions.find("MSFT_lod");
        if (lod != n.extensions.end() && lod->second.IsObject() && lod->second.Has("ids")) {
            const tinygltf::Value &ids = lod->second.Get("ids");
            if (!ids.IsArray()) throw Failure{2, "MSFT_lod.ids is not an array"};
            for (int i = 0; i < int(ids.ArrayLen()) && levels.size() < SY_GLTF_MAX_LODS; i++) {
                if (!ids.Get(i).IsNumber()) throw Failure{2, "MSFT_lod.ids holds a non-number"};
                int id = ids.Get(i).GetNumberAsInt();
                if (id < 0 || size_t(id) >= m.nodes.size()) throw Failure{2, "MSFT_lod names node " + std::to_string(id) + ", which does not exist"};
                levels.push_back(id);
            }
        }
        o.n_levels = int(levels.size());
        for (int l = 0; l < SY_GLTF_MAX_LODS; l++) o.coverage[l] = -1;
        if (n.extras.IsObject() && n.extras.Has("MSFT_screencoverage")) {
            const tinygltf::Value &c = n.extras.Get("MSFT_screencoverage");
            if (c.IsArray())
                for (int l = 0; l < int(c.ArrayLen()) && l < SY_GLTF_MAX_LODS; l++)
                    if (c.Get(l).IsNumber()) o.coverage[l] = float(c.Get(l).GetNumberAsDouble());
        }
        wind_table(n, o);
        objects.push_back(o);
        int index = int(objects.size()) - 1;
        // MSFT_lod: a coarser level's node takes the root's place, with its own transform.
        for (int l = 0; l < int(levels.size()); l++) node(levels[size_t(l)], identity(), 0, index, l);
    }
};

void free_scene(sy_gltf_scene *s)
{
    for (size_t i = 0; i < s->n_primitives; i++) {
        sy_gltf_primitive &p = s->primitives[i];
        for (float *f : {p.position, p.normal, p.tangent, p.uv, p.color, p.wind_w, p.wind_branch, p.wind_anchor, p.wind_level_stiffness})
            std::free(f);
        std::free(p.indices);
    }
    std::free(s->primitives);
    std::free(s->meshes);
    std::free(s->materials);
    std::free(s->textures);
    for (size_t i = 0; i < s->n_images; i++) std::free(s->images[i].pixels);
    std::free(s->images);
    for (size_t i = 0; i < s->n_draws; i++) {
        sy_gltf_draw &d = s->draws[i];
        for (float *f : {d.instance_matrix, d.inst_wind_w, d.inst_wind_branch, d.inst_wind_anchor, d.inst_wind_level_stiffness}) std::free(f);
    }
    std::free(s->draws);
    for (size_t i = 0; i < s->n_objects; i++) std::free(s->objects[i].wind);
    std::free(s->objects);
    std::memset(s, 0, sizeof *s);
}

} // namespace

extern "C" void sy_gltf_scene_free(sy_gltf_scene *s)
{
    if (s) free_scene(s);
}

static int read_scene(const char *path, sy_gltf_scene *out, char *msg, size_t msg_size)
{
    std::memset(out, 0, sizeof *out);
    try {
        tinygltf::Model model;
        if (!load_model(path, model, kDecodeImages, msg, msg_size)) return 2;
        SceneBuilder b{model, *out, {}, {}, {}, {}};
        b.build_images();
        b.build_textures();
        b.build_materials();
        b.build_meshes();
        std::vector<int> roots = scene_roots(model);
        for (int r : roots) b.object(r);
        // Objects that draw nothing (cameras, lights, empty groups) are dropped.
        std::vector<int> remap(b.objects.size(), -1);
        std::vector<sy_gltf_object> kept;
        for (size_t i = 0; i < b.objects.size(); i++)
            if (b.objects[i].n_triangles[0] > 0) {
                remap[i] = int(kept.size());
                kept.push_back(b.objects[i]);
            } else
                std::free(b.objects[i].wind);
        b.objects.swap(kept);
        std::vector<sy_gltf_draw> dk;
        for (sy_gltf_draw &d : b.draws)
            if (remap[size_t(d.object)] >= 0) {
                d.object = remap[size_t(d.object)];
                dk.push_back(d);
            } else
                for (float *f : {d.instance_matrix, d.inst_wind_w, d.inst_wind_branch, d.inst_wind_anchor, d.inst_wind_level_stiffness}) std::free(f);
        b.draws.swap(dk);
        for (const sy_gltf_draw &d : b.draws) {
            const sy_gltf_mesh &mesh = b.meshes[size_t(d.mesh)];
            for (int pi = 0; pi < mesh.n_primitives; pi++) {
                const sy_gltf_primitive &p = b.prims[size_t(mesh.first_primitive + pi)];
                if (p.material >= 0) {
                    const sy_gltf_material &mt = out->materials[p.material];
                    if ((mt.base_color_texture >= 0 || mt.normal_texture >= 0) && !p.uv)
                        throw Failure{2, "mesh " + std::string(mesh.name) + " has textures but no TEXCOORD_0"};
                }
            }
        }
        out->n_primitives = b.prims.size();
        out->primitives = c_copy(b.prims);
        b.prims.clear();
        out->n_meshes = b.meshes.size();
        out->meshes = c_copy(b.meshes);
        out->n_draws = b.draws.size();
        out->draws = c_copy(b.draws);
        b.draws.clear();
        out->n_objects = b.objects.size();
        out->objects = c_copy(b.objects);
        b.objects.clear();
        if (out->n_objects == 0) {
            free_scene(out);
            set_msg(msg, msg_size, path, "no triangle mesh in the scene");
            return 2;
        }
        out->has_origin = asset_origin(model, out->origin);
        return 0;
    } catch (const Failure &f) {
        free_scene(out);
        set_msg(msg, msg_size, path, f.what);
        return f.code;
    } catch (const std::bad_alloc &) {
        free_scene(out);
        set_msg(msg, msg_size, path, "out of memory");
        return 3;
    } catch (const std::exception &e) {
        free_scene(out);
        set_msg(msg, msg_size, path, std::string("invalid glTF: ") + e.what());
        return 2;
    }
}

extern "C" sy_code sy_gltf_read_scene(const char *path, sy_gltf_scene *out, sy_error *err)
{
    char msg[1024];
    int rc = read_scene(path, out, msg, sizeof msg);
    if (rc == 0) return SY_OK;
    return sy_fail(err, rc == 3 ? SY_EINTERNAL : SY_EINPUT, "%s", msg);
}
