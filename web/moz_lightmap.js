// GLTFLoader plugin for the material extension MOZ_lightmap {"index", "texCoord", "intensity"} that
// scripts/export_lightmaps.py writes: loader.register( parser => new MozLightmapExtension( parser ) ).
// The texture is linear data (E / max E), so it stays NoColorSpace; three.js adds
// texel.rgb * lightMapIntensity to the irradiance that the material's diffuse term shades with base colour / pi.
import { NoColorSpace } from 'three';

export const MOZ_LIGHTMAP = 'MOZ_lightmap';

export class MozLightmapExtension {

	constructor( parser ) {

		this.parser = parser;
		this.name = MOZ_LIGHTMAP;

	}

	extendMaterialParams( materialIndex, materialParams ) {

		const def = this.parser.json.materials[ materialIndex ];
		const ext = def.extensions && def.extensions[ this.name ];
		if ( ! ext ) return Promise.resolve();
		materialParams.lightMapIntensity = ext.intensity !== undefined ? ext.intensity : 1.0;
		return this.parser.assignTexture( materialParams, 'lightMap', { index: ext.index, texCoord: ext.texCoord ?? 0 },
			NoColorSpace );

	}

}
