// Probe grids in three.js r187 (WebGLRenderer, headless Chromium): shprobe's exported grid
// rendered on a white Lambertian surface at given points and normals, and three.js's own
// LightProbeGridWebGL bake of a scene, read back coefficient by coefficient.
// Driven by tests/grids/test_grid_export_three*.py and bench/bench_grid_three.py.
import * as THREE from 'three';
import { LightProbeGridWebGL } from 'three/addons/lighting/LightProbeGridWebGL.js';
import { loadShprobeGrid } from './shprobe_grid_loader.mjs';

function makeRenderer() {

	const canvas = document.createElement( 'canvas' );
	canvas.width = canvas.height = 1;
	const renderer = new THREE.WebGLRenderer( { canvas, antialias: false } );
	renderer.setClearColor( 0x000000, 0 );
	return renderer;

}

function rendererInfo( renderer ) {

	const gl = renderer.getContext();
	const debug = gl.getExtension( 'WEBGL_debug_renderer_info' );
	return { renderer: debug ? gl.getParameter( debug.UNMASKED_RENDERER_WEBGL ) : gl.getParameter( gl.RENDERER ),
		version: THREE.REVISION };

}

// One pixel per sample: a small screen triangle over the pixel's centre whose three vertices
// all carry the sample's world position and normal, so the fragment sees exactly those.
export function renderSamples( doc, points, normals, options = {} ) {

	const renderer = makeRenderer();
	const n = points.length / 3;
	const W = 64, H = Math.ceil( n / W );
	const pos = new Float32Array( n * 9 ), nrm = new Float32Array( n * 9 ), ndc = new Float32Array( n * 6 );
	const corners = [ [ 0.1, 0.1 ], [ 0.9, 0.1 ], [ 0.5, 0.9 ] ]; // counter-clockwise: front face
	for ( let i = 0; i < n; i ++ ) {
		const px = i % W, py = Math.floor( i / W );
		for ( let v = 0; v < 3; v ++ ) {
			for ( let a = 0; a < 3; a ++ ) {
				pos[ i * 9 + v * 3 + a ] = points[ i * 3 + a ];
				nrm[ i * 9 + v * 3 + a ] = normals[ i * 3 + a ];
			}
			ndc[ i * 6 + v * 2 ] = ( px + corners[ v ][ 0 ] ) / W * 2 - 1;
			ndc[ i * 6 + v * 2 + 1 ] = ( py + corners[ v ][ 1 ] ) / H * 2 - 1;
		}
	}
	const geometry = new THREE.BufferGeometry();
	geometry.setAttribute( 'position', new THREE.BufferAttribute( pos, 3 ) );
	geometry.setAttribute( 'normal', new THREE.BufferAttribute( nrm, 3 ) );
	geometry.setAttribute( 'pixelNdc', new THREE.BufferAttribute( ndc, 2 ) );
	const material = new THREE.MeshLambertMaterial( { color: 0xffffff } );
	material.onBeforeCompile = ( shader ) => {
		shader.vertexShader = 'attribute vec2 pixelNdc;\n' + shader.vertexShader.replace(
			'#include <fog_vertex>', '#include <fog_vertex>\n\tgl_Position = vec4( pixelNdc, 0.0, 1.0 );' );
	};
	const mesh = new THREE.Mesh( geometry, material );
	mesh.frustumCulled = false;
	const scene = new THREE.Scene();
	scene.add( mesh );
	const grid = loadShprobeGrid( doc );
	scene.add( grid );
	const camera = new THREE.PerspectiveCamera( 50, 1, 0.1, 100 );
	camera.position.set( 0.3, 1.7, 9.0 ); // anywhere: the lighting is in world space
	camera.lookAt( 0, 1, 0 );
	const target = new THREE.WebGLRenderTarget( W, H, { type: THREE.FloatType } );
	renderer.setRenderTarget( target );
	renderer.render( scene, camera );
	const buf = new Float32Array( W * H * 4 );
	renderer.readRenderTargetPixels( target, 0, 0, W, H, buf );
	renderer.setRenderTarget( null );
	const rgb = [];
	for ( let i = 0; i < n; i ++ ) rgb.push( buf[ i * 4 ], buf[ i * 4 + 1 ], buf[ i * 4 + 2 ] );
	const info = rendererInfo( renderer );
	renderer.dispose();
	return { rgb, info };

}

// Every coefficient of a LightProbeGridWebGL atlas, read with texelFetch into a float target:
// flat (((iz*ny + iy)*nx + ix)*9 + k)*3 + rgb, the order of the shprobe three export.
function readAtlas( renderer, grid ) {

	const { x: nx, y: ny, z: nz } = grid.resolution;
	const W = nx * ny * nz, H = 7;
	const material = new THREE.ShaderMaterial( {
		uniforms: { atlas: { value: grid.texture }, res: { value: new THREE.Vector3( nx, ny, nz ) } },
		vertexShader: 'void main() { gl_Position = vec4( position.xy, 0.0, 1.0 ); }',
		fragmentShader: `
			uniform highp sampler3D atlas;
			uniform vec3 res;
			void main() {
				int nx = int( res.x ), ny = int( res.y ), nz = int( res.z );
				int p = int( gl_FragCoord.x ), t = int( gl_FragCoord.y );
				int ix = p % nx, iy = ( p / nx ) % ny, iz = p / ( nx * ny );
				gl_FragColor = texelFetch( atlas, ivec3( ix, iy, t * ( nz + 2 ) + 1 + iz ), 0 );
			}`
	} );
	const quad = new THREE.Mesh( new THREE.PlaneGeometry( 2, 2 ), material );
	quad.frustumCulled = false;
	const scene = new THREE.Scene();
	scene.add( quad );
	const target = new THREE.WebGLRenderTarget( W, H, { type: THREE.FloatType, depthBuffer: false } );
	renderer.setRenderTarget( target );
	renderer.render( scene, new THREE.OrthographicCamera( - 1, 1, 1, - 1, 0, 1 ) );
	const buf = new Float32Array( W * H * 4 );
	renderer.readRenderTargetPixels( target, 0, 0, W, H, buf );
	renderer.setRenderTarget( null );
	target.dispose();
	const out = new Array( W * 27 );
	for ( let t = 0; t < 7; t ++ ) {
		for ( let p = 0; p < W; p ++ ) {
			for ( let ch = 0; ch < 4; ch ++ ) {
				const j = t * 4 + ch;
				if ( j < 27 ) out[ p * 27 + j ] = buf[ ( t * W + p ) * 4 + ch ];
			}
		}
	}
	return out;

}

// three.js's own bake: the scene (one mesh, Lambertian grey `albedo`) under an environment
// shown as scene.background (lat-long float RGBA, three.js's equirect mapping) and lighting
// the surfaces through a LightProbe holding its SH (no shadows: three.js's probe light).
export function bakeThree( job ) {

	const renderer = makeRenderer();
	const scene = new THREE.Scene();
	const env = new THREE.DataTexture( new Float32Array( job.env ), job.envWidth, job.envHeight,
		THREE.RGBAFormat, THREE.FloatType );
	env.mapping = THREE.EquirectangularReflectionMapping;
	env.colorSpace = THREE.LinearSRGBColorSpace;
	env.magFilter = env.minFilter = THREE.LinearFilter;
	env.needsUpdate = true;
	scene.background = env;
	scene.add( new THREE.LightProbe( new THREE.SphericalHarmonics3().fromArray( job.sh ) ) );
	let geometry = new THREE.BufferGeometry();
	geometry.setAttribute( 'position', new THREE.BufferAttribute( new Float32Array( job.vertices ), 3 ) );
	geometry.setIndex( job.faces );
	geometry = geometry.toNonIndexed(); // flat normals per face
	geometry.computeVertexNormals();
	const a = job.albedo;
	scene.add( new THREE.Mesh( geometry, new THREE.MeshLambertMaterial( { color: new THREE.Color( a, a, a ) } ) ) );
	const [ nx, ny, nz ] = job.resolution;
	const b = job.bounds;
	const grid = new LightProbeGridWebGL( b[ 3 ] - b[ 0 ], b[ 4 ] - b[ 1 ], b[ 5 ] - b[ 2 ], nx, ny, nz );
	grid.position.set( ( b[ 0 ] + b[ 3 ] ) / 2, ( b[ 1 ] + b[ 4 ] ) / 2, ( b[ 2 ] + b[ 5 ] ) / 2 );
	grid.updateBoundingBox();
	const options = { cubemapSize: job.cubemapSize ?? 8 };
	const seconds = [];
	let coefficients = null;
	for ( let run = 0; run < ( job.runs ?? 2 ); run ++ ) {
		const t0 = performance.now();
		grid.bake( renderer, scene, options );
		coefficients = readAtlas( renderer, grid ); // the readback waits for the GPU
		seconds.push( ( performance.now() - t0 ) / 1000 );
	}
	const info = rendererInfo( renderer );
	grid.dispose();
	renderer.dispose();
	return { seconds, coefficients, info };

}
