#version 430
// Visibility-raster vertex stage. LAYER_MODE 0: one instance per eye, gl_Layer written here
// (GL_ARB_shader_viewport_layer_array / GL_AMD_vertex_shader_layer). LAYER_MODE 1: the
// geometry stage (visibility.geom) picks the layer; this stage passes the position through.
// LAYER_MODE 2: GL_OVR_multiview2, the driver runs this stage once per view (gl_ViewID_OVR).
#if LAYER_MODE == 0
#extension GL_ARB_shader_viewport_layer_array : enable
#extension GL_AMD_vertex_shader_layer : enable
#elif LAYER_MODE == 2
#extension GL_OVR_multiview2 : require
layout(num_views = LAYERS) in;
#endif

layout(location = 0) in vec3 in_position;  // scene-local

uniform mat4 view_proj[2];   // scene-local -> clip, per layer (eye)
uniform int base_layer;      // first layer this draw writes (mono passes: the eye's index)

void main() {
#if LAYER_MODE == 0
    int layer = base_layer + gl_InstanceID;
    gl_Position = view_proj[layer] * vec4(in_position, 1.0);
    gl_Layer = layer;
#elif LAYER_MODE == 2
    gl_Position = view_proj[int(gl_ViewID_OVR)] * vec4(in_position, 1.0);
#else
    gl_Position = vec4(in_position, 1.0);
#endif
}
