// Shadow pass: depth only, alpha-tested leaves cast their cut-out shapes.
in vec3 v_world;
in vec3 v_normal;
in vec4 v_tangent;
in vec2 v_uv;
in vec4 v_color;
flat in float v_fade;
flat in float v_fade_sign;
uniform vec4 u_base_color;
uniform sampler2D u_base_tex;
uniform int u_has_base_tex;
uniform int u_alpha_mode;
uniform float u_alpha_cutoff;
void main()
{
    float a = u_base_color.a * v_color.a;
    if (u_has_base_tex != 0) a *= texture(u_base_tex, v_uv).a;
    if (u_alpha_mode == 1 && a < u_alpha_cutoff) discard;
    if (u_alpha_mode == 2 && a < 0.5) discard;
}
