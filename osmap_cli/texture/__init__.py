"""The texture core that `osmap synth` and `osmap solid` both stand on, one job a module:

- pyramid: resize, half_size, build_pyramid (exemplar pyramids, OpenImageIO filtering)
- levels: level_count (how many pyramid levels the exemplars and the output allow)
- features: neighbourhood_vectors, appearance_features (PCA appearance space, one exemplar or
  several on a joint basis), pca_basis (the principal axes both fit), feature_variance
- histogram: match_quantiles (values moved to a reference distribution, rank by rank)
- references: similar_positions (k-NN table of similar exemplar positions) and the sizes of its
  reference grid (SYNTH_REFERENCES, SOLID_REFERENCES)
- occupancy: occupancy (blurred use of each exemplar pixel, relative to uniform use)
"""
