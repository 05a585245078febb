#version 430
// HUD quads in window pixels, origin top-left.
in vec2 in_pos;
in vec2 in_uv;
in vec4 in_color;
out vec2 uv;
out vec4 color;

uniform vec2 viewport;  // framebuffer size in pixels

void main() {
    uv = in_uv;
    color = in_color;
    gl_Position = vec4(in_pos.x / viewport.x * 2.0 - 1.0, 1.0 - in_pos.y / viewport.y * 2.0, 0.0, 1.0);
}
