// The glTF reader's geometry side (tinygltf shim): the triangle soup of a
// glTF scene in Sylva's world frame (Z up).
#include "stages/gltf/gltf_read.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

using Mat4 = std::array<double, 16>; // column-major, as glTF stores matrices

constexpr size_t kMaxTriangles = size_t(1) << 28; // 2.7e8 triangles, ~19 GB of doubles

struct Failure {
    int code;
    std::string what;
};

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
    std::vector<size_t> label(n_vertices, SIZE_MAX), part(idx.size() / 3);
    size_t next = 0;
    for (size_t t = 0; t + 2 < idx.size(); t += 3) {
        size_t r = find(idx[t]);
        if (label[r] == SIZE_MAX) label[r] = next++;
        part[t / 3] = label[r];
    }
    return part;
}

struct Reader {
    const tinygltf::Model &m;
    std::vector<double> out;
    std::vector<size_t> hull; // per triangle: 0, or 1 + the closed hull it belongs to
    size_t n_hulls = 0;
    size_t visits = 0;

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
            views.emplace_back(m, v.GetNumberAsInt(), "EXT_mesh_gpu_instancing");
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

    void emit(const Mat4 &xf, const AccessorView &pos, size_t a, size_t b, size_t c, size_t hull_id)
    {
        if (out.size() / 9 >= kMaxTriangles) throw Failure{2, "more than 2^28 triangles"};
        hull.push_back(hull_id);
        for (size_t v : {a, b, c}) {
            double p[3] = {pos.get(v, 0), pos.get(v, 1), pos.get(v, 2)}, w[3];
            for (int r = 0; r < 3; r++) w[r] = xf[r] * p[0] + xf[4 + r] * p[1] + xf[8 + r] * p[2] + xf[12 + r];
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
                if (!(v >= 0 && v < double(pos.count()))) throw Failure{2, "index " + std::to_string(size_t(v)) + " beyond the vertex count"};
                idx[i] = size_t(v);
            }
        } else {
            idx.resize(pos.count());
            for (size_t i = 0; i < idx.size(); i++) idx[i] = i;
        }
        // Hulls are plain triangle lists (as Sylva writes them); each instance is hulls of its own.
        hulls = hulls && mode == TINYGLTF_MODE_TRIANGLES;
        std::vector<size_t> part = hulls ? components(idx, pos.count()) : std::vector<size_t>();
        size_t n_parts = 0;
        for (size_t p : part) n_parts = std::max(n_parts, p + 1);
        for (const Mat4 &xf : xfs) {
            if (mode == TINYGLTF_MODE_TRIANGLES)
                for (size_t i = 0; i + 2 < idx.size(); i += 3)
                    emit(xf, pos, idx[i], idx[i + 1], idx[i + 2], hulls ? n_hulls + 1 + part[i / 3] : 0);
            else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP)
                for (size_t i = 0; i + 2 < idx.size(); i++)
                    i % 2 ? emit(xf, pos, idx[i + 1], idx[i], idx[i + 2], 0) : emit(xf, pos, idx[i], idx[i + 1], idx[i + 2], 0);
            else
                for (size_t i = 1; i + 1 < idx.size(); i++) emit(xf, pos, idx[0], idx[i], idx[i + 1], 0);
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

// Evaluation needs geometry only: skip decoding textures.
bool skip_image(tinygltf::Image *, const int, std::string *, std::string *, int, int, const unsigned char *, int, void *)
{
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

} // namespace

static int read_triangles(const char *path, double **tri, size_t *n_tri, size_t **hull, char *msg, size_t msg_size)
{
    *tri = nullptr;
    *hull = nullptr;
    *n_tri = 0;
    try {
        tinygltf::TinyGLTF loader;
        loader.SetImageLoader(skip_image, nullptr);
        tinygltf::Model model;
        std::string err, warn;
        FILE *fp = std::fopen(path, "rb");
        if (!fp) {
            set_msg(msg, msg_size, path, "cannot open");
            return 2;
        }
        unsigned char magic[4] = {0, 0, 0, 0};
        size_t got = std::fread(magic, 1, 4, fp);
        std::fclose(fp);
        bool binary = got == 4 && std::memcmp(magic, "glTF", 4) == 0;
        bool ok = binary ? loader.LoadBinaryFromFile(&model, &err, &warn, path)
                         : loader.LoadASCIIFromFile(&model, &err, &warn, path);
        if (!ok) {
            set_msg(msg, msg_size, path, err.empty() ? "not a readable glTF file" : "invalid glTF: " + err);
            return 2;
        }
        Reader r{model, {}, {}};
        std::vector<int> roots;
        if (!model.scenes.empty()) {
            int s = model.defaultScene >= 0 ? model.defaultScene : 0;
            if (size_t(s) >= model.scenes.size()) throw Failure{2, "default scene index out of range"};
            roots = model.scenes[size_t(s)].nodes;
        } else {
            // No scene: every node that is nobody's child is a root.
            std::vector<char> child(model.nodes.size(), 0);
            for (const auto &n : model.nodes)
                for (int c : n.children)
                    if (c >= 0 && size_t(c) < child.size()) child[size_t(c)] = 1;
            for (size_t i = 0; i < model.nodes.size(); i++)
                if (!child[i]) roots.push_back(int(i));
        }
        for (int n : roots) r.node(n, identity(), 0);
        // `sylva mesh` centres the tree at its base and keeps the world position
        // of that point in asset.extras.origin (Z up): put the tree back there.
        const tinygltf::Value &origin = model.asset.extras.Get("origin");
        if (origin.IsArray() && origin.ArrayLen() == 3 && origin.Get(0).IsNumber() && origin.Get(1).IsNumber() &&
            origin.Get(2).IsNumber())
            for (size_t i = 0; i < r.out.size(); i++) r.out[i] += origin.Get(int(i % 3)).GetNumberAsDouble();
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
    int rc = read_triangles(path, tri, n_tri, hull, msg, sizeof msg);
    if (rc == 0) return SY_OK;
    return sy_fail(err, rc == 3 ? SY_EINTERNAL : SY_EINPUT, "%s", msg);
}
