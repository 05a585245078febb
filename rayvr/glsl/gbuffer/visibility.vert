#version 430
// G-buffer vertex stage. LAYER_MODE 0: one instance per eye, gl_Layer written here
// (GL_ARB_shader_viewport_layer_array / GL_AMD_vertex_shader_layer). LAYER_MODE 1: the
// geometry stage (gbuffer.geom) picks the layer; this stage only passes data through.
#if LAYER_MODE == 0
#extension GL_ARB_shader_viewport_layer_array : enable
#extension GL_AMD_vertex_shader_layer : enable
#endif

layout(location = 0) in vec3 in_position;  // scene-local
layout(location = 1) in vec3 in_normal;
layout(location = 2) in vec2 in_uv;

uniform mat4 view_proj[2];   // scene-local -> clip, per layer (eye)
uniform vec4 view_z_row[2];  // scene-local -> view-space z, per layer
uniform int base_layer;      // first layer this draw writes (mono passes: the eye's index)

out VertexData {
    vec3 position;
    vec3 normal;
    vec2 uv;
    float view_depth;
} vs_out;

void main() {
    vs_out.position = in_position;
    vs_out.normal = in_normal;
    vs_out.uv = in_uv;
#if LAYER_MODE == 0
    int layer = base_layer + gl_InstanceID;
    vec4 p = vec4(in_position, 1.0);
    gl_Position = view_proj[layer] * p;
    vs_out.view_depth = -dot(view_z_row[layer], p);
    gl_Layer = layer;
#else
    gl_Position = vec4(in_position, 1.0);
    vs_out.view_depth = 0.0;
#endif
}
