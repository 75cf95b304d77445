// The three.js the viewer page uses, and nothing else: tools/vendor_js.sh bundles this file with
// esbuild (tree-shaken, minified) into the package data as vendor/three/three.min.js, so the page
// parses ~0.5 MB instead of three.js's 2 MB of modules before its first frame. Keep it in step
// with the THREE.* names viewer.js uses (tests/viewer/test_viewer.py checks that the page loads).
export {
  BufferAttribute, BufferGeometry, ClampToEdgeWrapping, Color, DataTexture, FloatType, GLSL3,
  HalfFloatType, LightProbe, LinearFilter, LinearSRGBColorSpace, Matrix3, Matrix4, Mesh,
  OrthographicCamera, PerspectiveCamera, PlaneGeometry, RGBAFormat, RepeatWrapping, Scene,
  ShaderMaterial, SphericalHarmonics3, Vector3, WebGLRenderTarget, WebGLRenderer,
} from 'three';
export { OrbitControls } from 'three/addons/controls/OrbitControls.js';
