#version 430
// Layered visibility raster without vertex-stage gl_Layer: one invocation per eye.
layout(triangles, invocations = LAYERS) in;
layout(triangle_strip, max_vertices = 3) out;

uniform mat4 view_proj[2];
uniform int base_layer;

void main() {
    int layer = base_layer + gl_InvocationID;
    for (int i = 0; i < 3; ++i) {
        gl_Position = view_proj[layer] * gl_in[i].gl_Position;
        gl_Layer = layer;
        gl_PrimitiveID = gl_PrimitiveIDIn;
        EmitVertex();
    }
    EndPrimitive();
}
