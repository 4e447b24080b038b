// Preetham, Shirley & Smits (1999) daylight: Perez distributions of Y, x, y around the sun.
in vec2 v_ndc;
out vec4 o_color;
uniform mat4 u_inv_view_proj;
uniform vec3 u_eye;
uniform vec3 u_sun_dir;
uniform vec3 u_perez[5];      // A..E, each (Y, x, y)
uniform vec3 u_zenith;        // Y, x, y at the zenith
uniform vec3 u_perez_sun;     // F(0, theta_s) per channel (the normaliser)
uniform float u_sky_scale;    // luminance to render units
uniform vec3 u_sun_color;
uniform float u_exposure;

vec3 perez(float cos_theta, float gamma, float cos_gamma)
{
    return (1.0 + u_perez[0] * exp(u_perez[1] / max(cos_theta, 0.01))) *
           (1.0 + u_perez[2] * exp(u_perez[3] * gamma) + u_perez[4] * cos_gamma * cos_gamma);
}

void main()
{
    vec4 far = u_inv_view_proj * vec4(v_ndc, 1.0, 1.0);
    vec3 d = normalize(far.xyz / far.w - u_eye);
    float ct = max(d.y, 0.0);
    float cg = clamp(dot(d, u_sun_dir), -1.0, 1.0);
    vec3 Yxy = u_zenith * perez(ct, acos(cg), cg) / u_perez_sun;
    float Y = Yxy.x * u_sky_scale;
    // xyY -> XYZ -> linear sRGB
    float X = Yxy.y / max(Yxy.z, 1e-4) * Y, Z = (1.0 - Yxy.y - Yxy.z) / max(Yxy.z, 1e-4) * Y;
    vec3 rgb = mat3(3.2406, -0.9689, 0.0557, -1.5372, 1.8758, -0.2040, -0.4986, 0.0415, 1.0570) * vec3(X, Y, Z);
    rgb = max(rgb, vec3(0.0));
    if (d.y < 0.0) rgb = mix(rgb, vec3(0.25, 0.24, 0.22) * Y, clamp(-d.y * 8.0, 0.0, 1.0));
    if (cg > 0.99995) rgb += u_sun_color * 4.0;                  // the sun's disc (0.5 degrees)
    rgb *= u_exposure;
    rgb = rgb / (1.0 + rgb);
    o_color = vec4(pow(rgb, vec3(1.0 / 2.2)), 1.0);
}
