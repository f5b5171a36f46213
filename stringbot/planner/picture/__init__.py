"""Reading the picture: any PIL picture, cropped, grayed and scaled to the working size."""
