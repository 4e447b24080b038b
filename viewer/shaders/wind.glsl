// Beam-model branch sway (Habel 2009, ch. 4), shared by the lit and the shadow pass.
// Per branch (u_branches, 6 RGBA32F texels per row, one row per branch):
//  0: anchor.xyz, length L      1: axis t.xyz, c2      2: r.xyz, c4      3: s.xyz, parent
//  4: motion vector m.xy (texels/s in the level's motion texture), start offset.xy
//  5: level, stiffness, amplitude gain, natural frequency f_h
// A point at x along a branch moves by L * o(x), with u(x) = c2 x^2 + c4 x^4 scaled by the
// amplitude A_{r,s} read along the branch's trajectory through its level's motion texture
// (spectral synthesis, §4.5), plus the steady push of the wind (4.21), with the length
// correction of §4.4.2 (4.9-4.11, 4.23) and the normal update (4.26). Ancestors translate
// and turn their children about the attachment point (children follow parents, Fig. 4.12).
uniform sampler2D u_branches;
uniform sampler2DArray u_motion;   // RG = A_r, A_s per level (layer = level)
uniform int u_wind_on;
uniform float u_time;
uniform float u_wind_gain;         // user strength times the stop envelope
uniform float u_wind_steady;       // steady push (4.21) relative to the noise
uniform vec3 u_wind_dir;           // unit, asset frame
uniform int u_static_load;         // 1: only the steady push, no noise (tests)
uniform int u_n_branches;

vec4 branch_texel(int b, int k) { return texelFetch(u_branches, ivec2(k, b), 0); }

// One level's deflection at x: offset (metres) and slope vector g = u'_r r + u'_s s.
void beam(int b, float x, float tree_phase, out vec3 o, out vec3 g, out vec3 t, out vec3 base)
{
    vec4 t0 = branch_texel(b, 0), t1 = branch_texel(b, 1), t2 = branch_texel(b, 2), t3 = branch_texel(b, 3);
    vec4 t4 = branch_texel(b, 4), t5 = branch_texel(b, 5);
    float L = t0.w, c2 = t1.w, c4 = t2.w;
    t = t1.xyz;
    vec3 r = t2.xyz, s = t3.xyz;
    base = t0.xyz + t * (L * x);
    vec2 a = vec2(0.0);
    if (u_static_load == 0) {
        vec2 uv = (t4.zw + t4.xy * (u_time + tree_phase)) / vec2(textureSize(u_motion, 0).xy);
        a = texture(u_motion, vec3(uv, t5.x)).rg * t5.z;
    }
    // Steady push along the wind, projected on the branch's cross-section axes (4.21).
    a += vec2(dot(r, u_wind_dir), dot(s, u_wind_dir)) * u_wind_steady * t5.z;
    a *= u_wind_gain;
    float u = c2 * x * x + c4 * x * x * x * x;
    float du = 2.0 * c2 * x + 4.0 * c4 * x * x * x;
    vec2 ku = a * u, kd = a * du;                 // normalised deflection and slope per axis
    vec2 st = sqrt(1.0 + kd * kd);                // stretch s(x) (4.9)
    vec2 d = vec2(abs(kd.x) > 1e-6 ? ku.x / kd.x * (st.x - 1.0) : 0.0, abs(kd.y) > 1e-6 ? ku.y / kd.y * (st.y - 1.0) : 0.0);
    o = L * (-(d.x / st.x + d.y / st.y) * t + (ku.x / st.x) * r + (ku.y / st.y) * s);  // (4.13)
    g = kd.x * r + kd.y * s;
}

// Deforms a point (and its normal) of a vertex on branch b at w along the hierarchy.
void wind_deform(inout vec3 p, inout vec3 n, float branch, vec4 w, float tree_phase)
{
    if (u_wind_on == 0 || u_n_branches == 0) return;
    int b = int(branch + 0.5);
    if (b < 0 || b >= u_n_branches) return;
    int chain[4];
    int level = int(branch_texel(b, 5).x + 0.5);
    level = clamp(level, 0, 3);
    int c = b;
    for (int l = 3; l >= 0; l--) {
        if (l > level) { chain[l] = -1; continue; }
        chain[l] = c;
        int parent = int(branch_texel(c, 3).w + 0.5 * sign(branch_texel(c, 3).w));
        if (parent >= 0 && parent < u_n_branches) c = parent;
    }
    vec3 o, g, t, base;
    // Own branch: bend at x = w[level].
    beam(chain[level], w[level], tree_phase, o, g, t, base);
    p += o;
    n -= (dot(g, n)) * t;                          // (4.26)
    // Ancestors, nearest first: turn about the attachment point, then follow it.
    for (int l = level - 1; l >= 0; l--) {
        beam(chain[l], w[l], tree_phase, o, g, t, base);
        vec3 q = p - base;
        p += g * dot(t, q) - t * dot(g, q) + o;
        n += g * dot(t, n) - t * dot(g, n);
    }
}

// Leaf flutter (§4.7): translational flutter along the card normal, growing with the height
// along the card (x = v), and torsional flutter about the midrib (x = signed u), both with the
// linear deflection u(x) = A x; A comes from a turbulent field (the finest motion layer) sampled
// at the leaf's rest position moved against the wind (4.27's -W(t) offset).
uniform float u_flutter;
vec3 flutter(vec3 n, vec2 uv, vec3 anchor, float size, float tree_phase)
{
    if (u_wind_on == 0 || u_flutter <= 0.0) return vec3(0.0);
    vec3 q = anchor - u_wind_dir * (u_time + tree_phase) * 1.5;
    vec2 tl = texture(u_motion, vec3(q.x * 0.21 + q.y * 0.07, q.z * 0.21 - q.y * 0.05, 3.0)).rg;
    float vt = clamp(uv.y, 0.0, 1.0), ut = clamp(uv.x, 0.0, 1.0) * 2.0 - 1.0;
    return u_flutter * u_wind_gain * size * (tl.x * vt + 0.5 * tl.y * ut) * n;
}
