"""The texture core that `osmap synth` and `osmap solid` both stand on, one job a module:

- pyramid: resize, half_size, build_pyramid (exemplar pyramids, OpenImageIO filtering)
- levels: level_count (how many pyramid levels the exemplars and the output allow)
- features: neighbourhood_vectors, appearance_features (PCA appearance space, one exemplar or
  several on a joint basis), feature_variance
- references: similar_positions (k-NN table of similar exemplar positions)
- occupancy: occupancy (blurred use of each exemplar pixel, relative to uniform use)
"""
