// Ground plane: a square around the scene at the lowest point; with grass it is the carrier
// polygon at the top of the grass layer.
layout(location = 0) in vec2 a_xz;
uniform mat4 u_view_proj;
uniform float u_y;
out vec3 v_world;
void main()
{
    v_world = vec3(a_xz.x, u_y, a_xz.y);
    gl_Position = u_view_proj * vec4(v_world, 1.0);
}
