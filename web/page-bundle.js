// The page of `csrbf export --html`: three.js (npm), its GLTFLoader and meshopt decoder, and
// csrbf_deformation.js, bundled by esbuild into one classic script (window.CSRBF) that a page
// opened from file:// can load.
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';
import { CSRBFDeformation, CSRBFDeformationPlugin, CSRBF_GLSL } from './csrbf_deformation.js';

window.CSRBF = { THREE, GLTFLoader, MeshoptDecoder, CSRBFDeformation, CSRBFDeformationPlugin, CSRBF_GLSL };
