// Trees: Cook-Torrance for bark and the lit leaf side, Half-Life 2 translucency on the unlit
// side (Habel 2009 §3.3.8-3.3.9, eq. 3.23) or KHR_materials_diffuse_transmission, alpha test,
// sky ambient from spherical harmonics, sun shadow map, dithered LOD cross-fade.
in vec3 v_world;
in vec3 v_normal;
in vec4 v_tangent;
in vec2 v_uv;
in vec4 v_color;
flat in float v_fade;
flat in float v_fade_sign;
out vec4 o_color;

uniform vec4 u_base_color;
uniform sampler2D u_base_tex;      uniform int u_has_base_tex;
uniform sampler2D u_normal_tex;    uniform int u_has_normal_tex;  uniform float u_normal_scale;
uniform sampler2D u_mr_tex;        uniform int u_has_mr_tex;
uniform float u_metallic, u_roughness;
uniform vec3 u_emissive;
uniform int u_alpha_mode;          // 0 opaque, 1 mask, 2 blend
uniform float u_alpha_cutoff;
uniform int u_double_sided;
uniform float u_dt_factor;         // KHR_materials_diffuse_transmission
uniform vec3 u_dt_color;
uniform sampler2D u_dt_tex;        uniform int u_has_dt_tex;
uniform sampler2D u_dt_color_tex;  uniform int u_has_dt_color_tex;
uniform sampler2D u_hl2_adaxial;   uniform sampler2D u_hl2_abaxial;   // SYLVA_leaf_translucency
uniform int u_has_hl2;
uniform float u_hl2_min, u_hl2_max;
uniform int u_translucency;        // user toggle
uniform int u_mask;                // silhouette mode: white where the surface is

uniform vec3 u_sun_dir;            // towards the sun, world
uniform vec3 u_sun_color;
uniform vec3 u_sh[9];              // sky irradiance, SH order 2 (already convolved, /pi)
uniform vec3 u_eye;
uniform float u_exposure;
uniform int u_shadows;
uniform sampler2DShadow u_shadow_map;
uniform mat4 u_shadow_matrix;
uniform int u_wireframe;

float bayer4(vec2 fc)
{
    ivec2 p = ivec2(fc) & 3;
    int m[16] = int[16](0, 8, 2, 10, 12, 4, 14, 6, 3, 11, 1, 9, 15, 7, 13, 5);
    return (float(m[p.y * 4 + p.x]) + 0.5) / 16.0;
}

vec3 sh_irradiance(vec3 n)
{
    // Ramamoorthi & Hanrahan 2001: E(n) from the first nine coefficients (convolution folded in).
    return u_sh[0] + u_sh[1] * n.y + u_sh[2] * n.z + u_sh[3] * n.x + u_sh[4] * (n.x * n.y) + u_sh[5] * (n.y * n.z) +
           u_sh[6] * (3.0 * n.z * n.z - 1.0) + u_sh[7] * (n.x * n.z) + u_sh[8] * (n.x * n.x - n.y * n.y);
}

float shadow_at(vec3 p, vec3 n)
{
    if (u_shadows == 0) return 1.0;
    vec4 s = u_shadow_matrix * vec4(p + n * 0.02, 1.0);
    s.xyz /= s.w;
    if (any(lessThan(s.xyz, vec3(0.0))) || any(greaterThan(s.xyz, vec3(1.0)))) return 1.0;
    // PCF over 6 Poisson taps (the thesis's 2048^2 map with 6 samples).
    vec2 taps[6] = vec2[6](vec2(-0.326, -0.406), vec2(-0.840, -0.074), vec2(-0.696, 0.457), vec2(-0.203, 0.621),
                           vec2(0.962, -0.195), vec2(0.473, -0.480));
    vec2 texel = 1.5 / vec2(textureSize(u_shadow_map, 0));
    float sum = 0.0;
    for (int i = 0; i < 6; i++) sum += texture(u_shadow_map, vec3(s.xy + taps[i] * texel, s.z - 0.0015));
    return sum / 6.0;
}

// Cook-Torrance (1982): Beckmann distribution, their geometric term, Schlick's Fresnel.
vec3 cook_torrance(vec3 n, vec3 v, vec3 l, vec3 albedo, float metallic, float rough)
{
    vec3 h = normalize(v + l);
    float nl = max(dot(n, l), 0.0), nv = max(dot(n, v), 1e-4), nh = max(dot(n, h), 1e-4), vh = max(dot(v, h), 1e-4);
    float m = max(rough * rough, 0.03);
    float nh2 = nh * nh;
    float D = exp((nh2 - 1.0) / (m * m * nh2)) / (3.14159265 * m * m * nh2 * nh2);
    float G = min(1.0, min(2.0 * nh * nv / vh, 2.0 * nh * nl / vh));
    vec3 F0 = mix(vec3(0.04), albedo, metallic);
    vec3 F = F0 + (1.0 - F0) * pow(1.0 - vh, 5.0);
    vec3 spec = D * G * F / (4.0 * nv * max(nl, 1e-4));
    vec3 diffuse = (1.0 - F) * (1.0 - metallic) * albedo / 3.14159265;
    return (diffuse + spec) * nl;
}

// Half-Life 2 basis in tangent space (eq. 3.17 without the constant, applied below).
const vec3 H1 = vec3(-0.40824829, -0.70710678, 0.57735027);
const vec3 H2 = vec3(-0.40824829, 0.70710678, 0.57735027);
const vec3 H3 = vec3(0.81649658, 0.0, 0.57735027);

void main()
{
    // Dithered cross-fade between two LOD levels: the outgoing level keeps the pixels whose
    // threshold is below the fade, the incoming one the rest, so together they cover each pixel once.
    if (v_fade < 1.0) {
        float d = bayer4(gl_FragCoord.xy);
        if (v_fade_sign > 0.0 ? d >= v_fade : d < 1.0 - v_fade) discard;
    }
    vec4 base = u_base_color * v_color;
    if (u_has_base_tex != 0) base *= texture(u_base_tex, v_uv);
    if (u_alpha_mode == 1 && base.a < u_alpha_cutoff) discard;
    if (u_alpha_mode == 2 && base.a < 0.02) discard;
    if (u_mask != 0) { o_color = vec4(1.0); return; }
    if (u_wireframe != 0) { o_color = vec4(0.9, 0.95, 1.0, 1.0); return; }

    vec3 ng = normalize(v_normal);
    vec3 v = normalize(u_eye - v_world);
    bool back = !gl_FrontFacing;
    if (back && u_double_sided != 0) ng = -ng;
    vec3 t = normalize(v_tangent.xyz - ng * dot(ng, v_tangent.xyz));
    vec3 b = cross(ng, t) * v_tangent.w * (back ? -1.0 : 1.0);
    vec3 n = ng;
    if (u_has_normal_tex != 0) {
        vec3 tn = texture(u_normal_tex, v_uv).xyz * 2.0 - 1.0;
        tn.xy *= u_normal_scale;
        n = normalize(mat3(t, b, ng) * tn);
    }
    vec3 l = normalize(u_sun_dir);
    float rough = u_roughness, metallic = u_metallic;
    if (u_has_mr_tex != 0) {
        vec4 mr = texture(u_mr_tex, v_uv);
        rough *= mr.g;
        metallic *= mr.b;
    }
    // Offset the lookup towards the light: a back-lit leaf must not shadow itself.
    float sh = shadow_at(v_world, dot(ng, l) >= 0.0 ? ng : -ng);
    vec3 albedo = base.rgb;
    vec3 color = vec3(0.0);
    float nl = dot(ng, l);
    bool transmits = u_dt_factor > 0.0 || u_has_hl2 != 0;
    // KHR_materials_diffuse_transmission: the diffuse lobe splits into (1 - f) reflected and f
    // transmitted, the transmitted part tinted by its own colour only.
    float f = u_dt_factor;
    if (u_has_dt_tex != 0) f *= texture(u_dt_tex, v_uv).a;
    vec3 tc = u_dt_color;
    if (u_has_dt_color_tex != 0) tc *= texture(u_dt_color_tex, v_uv).rgb;
    if (transmits) albedo *= 1.0 - f;
    if (nl >= 0.0 || !transmits) {
        color += u_sun_color * sh * cook_torrance(n, v, l, albedo, metallic, rough);
    } else if (u_translucency != 0) {
        // Lit from behind: light through the leaf (only one of L_r, L_t is non-zero, §3.3.1).
        // The transmittance seen on this side, t = f x colour (docs/leafmaps.md writes it so).
        if (u_has_hl2 != 0) {
            // docs/leafmaps.md: the coefficients of the side the light hits, in that side's frame
            // (adaxial T, B, N; abaxial T, B, -N), two fetches and three dot products (eq. 3.23).
            vec3 N = normalize(v_normal);
            vec3 T = normalize(v_tangent.xyz - N * dot(N, v_tangent.xyz));
            vec3 B = cross(N, T) * v_tangent.w;
            bool adaxial = dot(l, N) > 0.0;
            vec3 w = vec3(dot(l, T), dot(l, B), adaxial ? dot(l, N) : -dot(l, N));
            vec3 h = u_hl2_min + (adaxial ? texture(u_hl2_adaxial, v_uv).rgb : texture(u_hl2_abaxial, v_uv).rgb) * (u_hl2_max - u_hl2_min);
            float rec = 0.69098830 * (h.r * dot(H1, w) + h.g * dot(H2, w) + h.b * dot(H3, w));   // sqrt(3/(2 pi))
            color += u_sun_color * sh * f * tc * max(rec, 0.0) / 3.14159265;
        } else {
            color += u_sun_color * sh * f * tc * (-nl) / 3.14159265;   // diffuse BTDF (3.24)
        }
    }
    color += albedo * sh_irradiance(n) * (1.0 - metallic);
    color += u_emissive;
    color *= u_exposure;
    color = color / (1.0 + color);                     // Reinhard
    o_color = vec4(pow(color, vec3(1.0 / 2.2)), 1.0);
}
