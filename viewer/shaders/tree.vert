// Trees: bark and leaves, lit pass and shadow pass (SHADOW_PASS defined).
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec3 a_normal;
layout(location = 2) in vec4 a_tangent;
layout(location = 3) in vec2 a_uv;
layout(location = 4) in vec4 a_color;
layout(location = 5) in vec4 a_wind_w;
layout(location = 6) in float a_wind_branch;
uniform mat4 u_view_proj;
uniform mat4 u_node;             // node-to-asset matrix
uniform mat3 u_node_normal;      // its inverse transpose (from the CPU)
uniform int u_instanced;         // leaves: per-instance matrices and wind
uniform int u_per_tree;          // instances (leaves) per tree copy: gl_InstanceID / u_per_tree = copy
uniform samplerBuffer u_trees;   // per tree copy: 4 texels of its asset-to-world matrix, 1 texel (fade, phase, sign, -)
uniform int u_tree_base;         // first slot of this draw in u_trees
uniform samplerBuffer u_inst;    // per instance (EXT_mesh_gpu_instancing): 4 texels of its matrix, _WIND_W, (_WIND_BRANCH, -, -, -)

out vec3 v_world;
out vec3 v_normal;
out vec4 v_tangent;
out vec2 v_uv;
out vec4 v_color;
flat out float v_fade;
flat out float v_fade_sign;

void main()
{
    int copy = u_tree_base + (u_instanced != 0 ? gl_InstanceID / max(u_per_tree, 1) : gl_InstanceID);
    mat4 tree = mat4(texelFetch(u_trees, copy * 5 + 0), texelFetch(u_trees, copy * 5 + 1),
                     texelFetch(u_trees, copy * 5 + 2), texelFetch(u_trees, copy * 5 + 3));
    vec4 extra = texelFetch(u_trees, copy * 5 + 4);
    int k = gl_InstanceID % max(u_per_tree, 1);
    mat4 inst = mat4(1.0);
    vec4 inst_w = vec4(0.0);
    float inst_branch = 0.0;
    if (u_instanced != 0) {
        inst = mat4(texelFetch(u_inst, k * 6 + 0), texelFetch(u_inst, k * 6 + 1), texelFetch(u_inst, k * 6 + 2),
                    texelFetch(u_inst, k * 6 + 3));
        inst_w = texelFetch(u_inst, k * 6 + 4);
        inst_branch = texelFetch(u_inst, k * 6 + 5).x;
    }
    mat4 local = u_node * inst;
    vec3 p = (local * vec4(a_position, 1.0)).xyz;
    // Normals: the node's inverse transpose, and for a TRS instance M = R S the exact
    // R S^-1 n = M (n / s^2) with s^2 the squared column lengths (no per-vertex inverse).
    mat3 im = mat3(inst);
    vec3 s2 = vec3(dot(im[0], im[0]), dot(im[1], im[1]), dot(im[2], im[2]));
    vec3 n = normalize(u_node_normal * (im * (a_normal / max(s2, vec3(1e-12)))));
    vec3 t = normalize(mat3(local) * (length(a_tangent.xyz) > 0.0 ? a_tangent.xyz : vec3(1.0, 0.0, 0.0)));
    if (u_instanced != 0) {
        float size = length(inst[0].xyz) * 0.5 + length(inst[1].xyz) * 0.5;
        vec3 hang = (u_node * vec4(inst[3].xyz, 1.0)).xyz;
        p += flutter(n, a_uv, hang, size * 0.1, extra.y);
        wind_deform(p, n, inst_branch, inst_w, extra.y);
    } else {
        wind_deform(p, n, a_wind_branch, a_wind_w, extra.y);
    }
    vec4 world = tree * vec4(p, 1.0);
    v_world = world.xyz;
    v_normal = normalize(mat3(tree) * n);
    v_tangent = vec4(normalize(mat3(tree) * t), a_tangent.w == 0.0 ? 1.0 : a_tangent.w);
    v_uv = a_uv;
    v_color = a_color;
    v_fade = extra.x;
    v_fade_sign = extra.z;
    gl_Position = u_view_proj * world;
}
