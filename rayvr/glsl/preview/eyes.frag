#version 430
// Shows the renderer's 8-bit eye images (already sRGB-encoded: copied as they are, so the
// window matches `rayvr capture`) in one viewport: one eye, or a red/cyan anaglyph of both.
in vec2 uv;
out vec4 frag;

uniform sampler2DArray eyes;  // layer 0 = first eye of the frame, GL bottom-up rows
uniform int layer;            // which layer this viewport shows
uniform int anaglyph;         // 1: red from layer 0 (left), green + blue from layer 1 (right)

void main() {
    if (anaglyph == 1) {
        vec3 l = texture(eyes, vec3(uv, 0.0)).rgb;
        vec3 r = texture(eyes, vec3(uv, 1.0)).rgb;
        // Half-colour anaglyph: the left eye's luminance in red gives less retinal rivalry on
        // saturated reds than its raw red channel would.
        frag = vec4(dot(l, vec3(0.299, 0.587, 0.114)), r.g, r.b, 1.0);
    } else {
        frag = vec4(texture(eyes, vec3(uv, float(layer))).rgb, 1.0);
    }
}
