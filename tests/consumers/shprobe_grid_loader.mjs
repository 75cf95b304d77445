// Loads a `shprobe grid export --format three` document into three.js's LightProbeGridWebGL
// (three r187, WebGLRenderer): the 27 coefficients of each probe are packed into the atlas the
// grid's shader samples — 7 RGBA sub-volumes stacked along Z, each nz + 2 slices deep (one
// padding slice at each end, a copy of the edge slice), texel t*4 + channel = coefficient j.
// docs/grid-exports.md prints this file; tests/grids/test_grid_export_three.py runs it in Chromium.
import { Data3DTexture, FloatType, LinearFilter, RGBAFormat } from 'three';
import { LightProbeGridWebGL } from 'three/addons/lighting/LightProbeGridWebGL.js';

export function loadShprobeGrid( doc ) {

	if ( doc.format !== 'shprobe-grid-three' ) throw new Error( 'not a shprobe three.js grid' );
	const [ nx, ny, nz ] = doc.resolution;
	const b = doc.bounds; // min x, y, z, max x, y, z
	const grid = new LightProbeGridWebGL( b[ 3 ] - b[ 0 ], b[ 4 ] - b[ 1 ], b[ 5 ] - b[ 2 ], nx, ny, nz );
	grid.position.set( ( b[ 0 ] + b[ 3 ] ) / 2, ( b[ 1 ] + b[ 4 ] ) / 2, ( b[ 2 ] + b[ 5 ] ) / 2 );
	grid.updateBoundingBox();

	const padded = nz + 2;
	const data = new Float32Array( nx * ny * 7 * padded * 4 );
	const c = doc.coefficients; // (((iz*ny + iy)*nx + ix)*9 + k)*3 + rgb
	for ( let t = 0; t < 7; t ++ ) {
		for ( let s = 0; s < padded; s ++ ) {
			const iz = Math.min( Math.max( s - 1, 0 ), nz - 1 );
			for ( let iy = 0; iy < ny; iy ++ ) {
				for ( let ix = 0; ix < nx; ix ++ ) {
					const src = ( ( iz * ny + iy ) * nx + ix ) * 27;
					const dst = ( ( ( t * padded + s ) * ny + iy ) * nx + ix ) * 4;
					for ( let ch = 0; ch < 4; ch ++ ) {
						const j = t * 4 + ch;
						data[ dst + ch ] = j < 27 ? c[ src + j ] : 0;
					}
				}
			}
		}
	}
	const texture = new Data3DTexture( data, nx, ny, 7 * padded );
	texture.format = RGBAFormat;
	texture.type = FloatType;
	texture.minFilter = LinearFilter;
	texture.magFilter = LinearFilter;
	texture.generateMipmaps = false;
	texture.unpackAlignment = 1;
	texture.needsUpdate = true;
	grid.texture = texture;
	return grid;

}
