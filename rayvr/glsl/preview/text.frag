#version 430
// Glyph coverage from the font atlas (one channel) times the vertex colour.
in vec2 uv;
in vec4 color;
out vec4 frag;

uniform sampler2D atlas;

void main() {
    frag = vec4(color.rgb, color.a * texture(atlas, uv).r);
}
