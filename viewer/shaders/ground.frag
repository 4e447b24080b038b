// Ground, and the ray-traced grass of Habel 2009 ch. 2: a regular grid of vertical textured
// slices along x and z, defined implicitly under the carrier polygon, hit analytically in ray
// order (eq. 2.1-2.2) and composited front to back with the over operator on premultiplied
// colour (eq. 2.3); what stays transparent after the last step is filled with the soil.
in vec3 v_world;
out vec4 o_color;
uniform vec3 u_eye;
uniform vec3 u_sun_dir;
uniform vec3 u_sun_color;
uniform vec3 u_sh[9];
uniform float u_exposure;
uniform int u_shadows;
uniform sampler2DShadow u_shadow_map;
uniform mat4 u_shadow_matrix;
uniform mat4 u_view_proj;
uniform float u_ground_y;
uniform int u_grass;
uniform float u_grass_height;   // metres
uniform float u_grass_spacing;  // metres between slices
uniform sampler2DArray u_grass_tex;
uniform float u_time;
uniform vec3 u_wind_dir;
uniform float u_wind_gain;
uniform int u_steps;

vec3 sh_irradiance(vec3 n)
{
    return u_sh[0] + u_sh[1] * n.y + u_sh[2] * n.z + u_sh[3] * n.x + u_sh[4] * (n.x * n.y) + u_sh[5] * (n.y * n.z) +
           u_sh[6] * (3.0 * n.z * n.z - 1.0) + u_sh[7] * (n.x * n.z) + u_sh[8] * (n.x * n.x - n.y * n.y);
}

float shadow_at(vec3 p)
{
    if (u_shadows == 0) return 1.0;
    vec4 s = u_shadow_matrix * vec4(p, 1.0);
    s.xyz /= s.w;
    if (any(lessThan(s.xyz, vec3(0.0))) || any(greaterThan(s.xyz, vec3(1.0)))) return 1.0;
    vec2 texel = 1.0 / vec2(textureSize(u_shadow_map, 0));
    float sum = 0.0;
    for (int i = -1; i <= 1; i++)
        for (int j = -1; j <= 1; j++) sum += texture(u_shadow_map, vec3(s.xy + vec2(i, j) * texel * 1.5, s.z - 0.002));
    return sum / 9.0;
}

vec3 soil(vec3 p)
{
    // Soil and sparse cover: incommensurate ripples, no visible period.
    float k = 0.5 + 0.18 * sin(p.x * 0.71 + sin(p.z * 0.37) * 2.0) + 0.14 * sin(p.z * 1.13 + sin(p.x * 0.53) * 1.7) +
              0.08 * sin((p.x + p.z) * 2.9);
    vec3 albedo = mix(vec3(0.20, 0.17, 0.11), vec3(0.25, 0.27, 0.13), k);
    vec3 up = vec3(0.0, 1.0, 0.0);
    return albedo * (u_sun_color * shadow_at(p) * max(dot(up, u_sun_dir), 0.0) / 3.14159265 + sh_irradiance(up));
}

float hash(float n) { return fract(sin(n * 12.9898) * 43758.5453); }

void finish(vec3 c, vec3 p)
{
    c *= u_exposure;
    c = c / (1.0 + c);
    o_color = vec4(pow(c, vec3(1.0 / 2.2)), 1.0);
    vec4 clip = u_view_proj * vec4(p, 1.0);
    gl_FragDepth = clamp(0.5 * clip.z / clip.w + 0.5, 0.0, 1.0);
}

void main()
{
    if (u_grass == 0) { finish(soil(v_world), v_world); return; }
    vec3 d = normalize(v_world - u_eye);
    if (d.y >= 0.0) discard;                      // looking up from below the carrier
    vec3 p = v_world;
    float sp = u_grass_spacing;
    // Next slice planes along the ray (x = i sp, z = j sp).
    vec2 dir = d.xz;
    vec2 cell = floor(p.xz / sp);
    vec2 next = (cell + step(0.0, dir)) * sp;
    vec2 tnext = vec2(abs(dir.x) > 1e-6 ? (next.x - p.x) / dir.x : 1e9, abs(dir.y) > 1e-6 ? (next.y - p.z) / dir.y : 1e9);
    vec2 tstep = vec2(abs(dir.x) > 1e-6 ? sp / abs(dir.x) : 1e9, abs(dir.y) > 1e-6 ? sp / abs(dir.y) : 1e9);
    float t_ground = (u_ground_y - p.y) / d.y;
    vec3 acc = vec3(0.0);
    float alpha = 0.0;
    vec3 depth_point = p + d * t_ground;
    bool depth_set = false;
    float light = 0.0;
    vec3 wind = u_wind_dir * u_wind_gain;
    for (int i = 0; i < 16; i++) {
        if (i >= u_steps) break;
        bool along_x = tnext.x < tnext.y;
        float t = along_x ? tnext.x : tnext.y;
        if (t >= t_ground) break;
        vec3 q = p + d * t;
        float h = (q.y - u_ground_y) / u_grass_height;                // 0 at the soil, 1 at the carrier
        float plane = along_x ? floor(q.x / sp + 0.5) : floor(q.z / sp + 0.5);
        float across = along_x ? q.z : q.x;
        // Wind: shear the lookup in proportion to the height (ch. 2, animation).
        float gust = sin(dot(q.xz, vec2(0.7, 0.5)) - u_time * 2.3) * 0.6 + sin(dot(q.xz, vec2(2.1, -1.7)) - u_time * 5.1) * 0.25;
        across += gust * h * h * 0.12 * length(wind) * (along_x ? sign(wind.z + 1e-3) : sign(wind.x + 1e-3));
        float layer = floor(hash(plane + (along_x ? 0.0 : 57.0)) * 4.0);
        vec4 s = texture(u_grass_tex, vec3(across / (u_grass_height * 2.0) + hash(plane) , 1.0 - h, layer));
        s.rgb *= s.a;                                                   // premultiplied
        acc += (1.0 - alpha) * s.rgb * (0.55 + 0.45 * h);              // darker near the soil
        alpha += (1.0 - alpha) * s.a;
        if (!depth_set && alpha >= 0.49) { depth_point = q; depth_set = true; }
        if (alpha > 0.99) break;
        if (along_x) tnext.x += tstep.x; else tnext.y += tstep.y;
    }
    vec3 up = vec3(0.0, 1.0, 0.0);
    vec3 lit = u_sun_color * shadow_at(depth_point) * (0.35 + 0.65 * max(u_sun_dir.y, 0.0)) / 3.14159265 + sh_irradiance(up);
    vec3 c = acc * lit + (1.0 - alpha) * soil(p + d * t_ground);
    finish(c, depth_point);
}
