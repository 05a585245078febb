#version 430
// Layered G-buffer without vertex-stage gl_Layer: one invocation per eye.
layout(triangles, invocations = LAYERS) in;
layout(triangle_strip, max_vertices = 3) out;

uniform mat4 view_proj[2];
uniform vec4 view_z_row[2];
uniform int base_layer;

in VertexData { vec3 position; vec3 normal; vec2 uv; float view_depth; } gs_in[];
out VertexData { vec3 position; vec3 normal; vec2 uv; float view_depth; } gs_out;

void main() {
    int layer = base_layer + gl_InvocationID;
    for (int i = 0; i < 3; ++i) {
        vec4 p = vec4(gs_in[i].position, 1.0);
        gl_Position = view_proj[layer] * p;
        gs_out.position = gs_in[i].position;
        gs_out.normal = gs_in[i].normal;
        gs_out.uv = gs_in[i].uv;
        gs_out.view_depth = -dot(view_z_row[layer], p);
        gl_Layer = layer;
        gl_PrimitiveID = gl_PrimitiveIDIn;
        EmitVertex();
    }
    EndPrimitive();
}
