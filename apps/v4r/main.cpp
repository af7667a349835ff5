// v4r - robust model-based object tracking. MIT licence.
int main() { return 0; }
