#version 330 core
// One ResamplePass of a pyramid plan (pyramid_cli/plan/model.py), from pyramid_cli/shaders/generate.py.
//
// Vectors are (x, y) = (column, row); row 0 of a texture is numpy row 0. Along AXIS (0: x, the
// columns; 1: y, the rows) output index j reads the source at the indices and weights of row j of
// the table texture u_table: texel (k, j) holds (source index, weight), indices already folded by
// the source's border mode on the CPU (a read of zero has weight 0). The indices are stored ones
// (a tile's window may have a guard band along AXIS); across AXIS there is none. The target's
// spare row and column (the texel after the last, read by later bilinear passes) repeat its edge,
// as in pass.frag.glsl.

// {{DEFINES}}

uniform sampler2D u_src;
uniform sampler2D u_table;
uniform int u_width;          // weights per output (the table's row width)
uniform ivec2 u_out_extent;   // stored (columns, rows) of the target

out vec4 frag_color;

void main() {
    ivec2 p = min(ivec2(gl_FragCoord.xy), u_out_extent - 1);
    int j = p[AXIS];
    vec4 acc = vec4(0.0);
    for (int k = 0; k < u_width; ++k) {
        vec2 e = texelFetch(u_table, ivec2(k, j), 0).rg;
        ivec2 q = p;
        q[AXIS] = int(e.x);
        acc += e.y * texelFetch(u_src, q, 0);
    }
    frag_color = acc;
}
