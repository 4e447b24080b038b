// Scan overlay: one point per scan sample, in the asset's frame.
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec3 a_color;
uniform mat4 u_view_proj;
uniform mat4 u_model;
uniform float u_point_size;
out vec3 v_color;
void main()
{
    v_color = a_color;
    gl_Position = u_view_proj * u_model * vec4(a_position, 1.0);
    gl_PointSize = u_point_size;
}
