"""System identification: data loading, TF identification, friction-error extraction, diagnosis."""
